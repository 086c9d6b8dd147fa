"""The live loop's CPU per frame on a colour camera's stream, as a user runs it:
``finray predict --force-only`` reading a 30 FPS H.264 stream over TCP
(:func:`finray.benchmarks.realtime.stream_benchmark`: decoding included, the predicting
process pinned to one core, the server to the other), for whichever finray is
importable (this tree's, or an older one's through PYTHONPATH), so that before and after
are measured with the same stream.

    python studies/realtime/stream_cpu.py TAG   # -> /tmp/finray-stream-<TAG>.json

The stream: 10 s of the synthetic orange finger of tests/recording_synth.py over a lit
grey background, bent 0-5 mm, at 640x480 and 1280x720; an untrained network of the
default size (its cost is a trained one's).
"""

import json
import sys
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

from finray.benchmarks.realtime import stream_benchmark, write_stream_video  # noqa: E402
from finray.model import FinRayNet, NetConfig  # noqa: E402
from finray.train import export_onnx, export_torchscript  # noqa: E402
from frame_cpu import PREPROCESS, frames_at  # noqa: E402  (this folder: the same synthetic finger)

KEYS = (
    "fps",
    "cpu_ms_per_frame",
    "cpu_ms_per_frame_run",
    "dropped_steady",
    "predicted",
    "received",
)


def main() -> None:
    tag = sys.argv[1]
    work = Path(f"/tmp/finray-stream-{tag}")
    work.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(0)
    net = FinRayNet(NetConfig(in_channels=1, base_channels=16, height=64, width=32)).eval()
    export_torchscript(net, work / "model.ts", PREPROCESS)
    export_onnx(net, work / "model.onnx")
    out = {}
    for h, w in ((480, 640), (720, 1280)):
        frames = frames_at(h, w)
        video = write_stream_video(frames, work / f"stream_{w}x{h}.ts", (h, w), 300)
        r = stream_benchmark(work / "model.ts", video, work / f"out_{w}x{h}", "force", cores=(1, 0))
        out[f"{w}x{h}"] = {k: r[k] for k in KEYS}
        print(tag, f"{w}x{h}", json.dumps(out[f"{w}x{h}"]), flush=True)
    Path(f"/tmp/finray-stream-{tag}.json").write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
