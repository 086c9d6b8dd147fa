"""`finray calibrate` under the one output policy (issue 55, finray.outputs): its file
and companions (<out>.model.ts(.json), .corner.png, .ingest/) move into place together
when complete; a used --out is refused without --overwrite; SIGINT or SIGTERM part way
leaves the earlier calibration as it was, in one line, exit code 130 / 143."""

import json
import signal
import time

import pytest
import torch

from finray.model import FinRayNet, NetConfig
from finray.train import History, export_torchscript, save_checkpoint

from helpers import PREPROCESS, start_finray
from recording_synth import write_take

pytestmark = pytest.mark.slow

CONFIG = (
    "evaluate:\n"
    "  sim2real: {heads: {members: 2, epochs: 0, steps: 50}, sampler: {max_steps: 2000}}\n"
)


def _state(folder):
    return {p.relative_to(folder).as_posix(): p.stat().st_mtime_ns for p in folder.rglob("*")}


def test_calibrate_moves_its_outputs_into_place_whole(tmp_path):
    torch.manual_seed(0)
    net = FinRayNet(NetConfig(in_channels=1, base_channels=4, height=64, width=32)).eval()
    save_checkpoint(net, History(), tmp_path / "model.pt")
    export_torchscript(net, tmp_path / "model.ts", PREPROCESS)
    write_take(
        tmp_path / "t1", size=(320, 240), duration_s=2.5, starts=(0.3, 1.35), ramp=0.35, hold=0.2
    )
    (tmp_path / "c.yaml").write_text(CONFIG)
    out = tmp_path / "rig" / "calibration.json"
    args = ["calibrate", "t1", "--model", "model.pt", "--out", str(out), "--config", "c.yaml"]
    t0 = time.perf_counter()
    p = start_finray(args, tmp_path)
    log, err = p.communicate(timeout=300)
    wall = time.perf_counter() - t0
    assert p.returncode in (0, 1), err  # 1: a chain that did not converge, all written
    first = _state(out.parent)
    assert {"calibration.json", "calibration.model.ts", "calibration.model.ts.json"} <= set(first)
    assert "calibration.corner.png" in first and "calibration.ingest/t1/shard.npz" in first
    assert ".part-" not in log  # the log names the files where they end up
    assert f"-> {out.parent / 'calibration.ingest' / 't1' / 'shard.npz'}" in log
    # the adapted model's settings keep its hash: predict checks it (no note)
    meta = json.loads((out.parent / "calibration.model.ts.json").read_text())
    assert set(meta["sha256"]) == {"torchscript", "settings"}
    p = start_finray(args, tmp_path)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 2 and "calibration.json exists (" in err and "--overwrite" in err
    # stopped part way, --overwrite: the earlier calibration stays as it was
    stopped = 0
    for frac, sig, what in [
        (0.5, signal.SIGTERM, "terminated"),
        (0.8, signal.SIGINT, "interrupted"),
    ]:
        # the first run's time includes a cold start (and other tests' load): a run
        # done before the signal came is run again with the signal sent sooner
        for k in range(4):
            p = start_finray([*args, "--overwrite"], tmp_path)
            time.sleep(frac * wall * 0.5**k)
            p.send_signal(sig)
            _, err = p.communicate(timeout=300)
            assert "Traceback" not in err, err
            if p.returncode in (0, 1):  # done before the signal: the new outputs, whole
                first = _state(out.parent)
                continue
            assert p.returncode == 128 + sig, err
            stopped += 1
            assert err.strip().splitlines()[-1] == f"finray calibrate: {what}; nothing written"
            assert _state(out.parent) == first
            assert [q.name for q in out.parent.iterdir() if ".part-" in q.name] == []
            break
    assert stopped  # a signal came while it ran
