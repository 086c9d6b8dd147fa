"""One output policy for every subcommand (issue 55, finray.outputs): a used --out is
refused in one line without --overwrite; the outputs are written beside --out and moved
into place when complete, so an earlier run stays intact until then; SIGINT and SIGTERM
at any moment leave the complete outputs or none, one line, exit code 130 / 143."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from finray.cli import main
from finray.errors import UsageError
from finray.outputs import Staged, catch_signals, held

from helpers import start_finray
from recording_synth import write_take

SMALL_TAKE = dict(size=(320, 240), duration_s=2.5, starts=(0.3, 1.35), ramp=0.35, hold=0.2)


def one_line(capsys, prefix: str) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith(f"{prefix}note:")]
    assert len(lines) == 1 and lines[0].startswith(prefix) and "Traceback" not in err, err
    return lines[0]


def names(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


def test_a_used_out_is_refused_without_overwrite(tmp_path):
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "old.csv").write_text("old")
    (tmp_path / "file").write_text("a file")
    (tmp_path / "empty").mkdir()
    with pytest.raises(UsageError, match=r"run holds another run's results \(1: old.csv\); give"):
        Staged(tmp_path / "run").check()
    with pytest.raises(UsageError, match="file is a file, not a folder"):
        Staged(tmp_path / "file", overwrite=True).check()
    with pytest.raises(UsageError, match="run is a folder, not a file"):
        Staged(tmp_path / "run", overwrite=True, kind="file").check()
    with pytest.raises(UsageError, match=r"file exists \(1: file\); give --overwrite"):
        Staged(tmp_path / "file", kind="file").check()
    (tmp_path / "cal.model.ts").write_text("")  # a companion of cal.json
    with pytest.raises(UsageError, match=r"cal.json exists \(1: cal.model.ts\)"):
        Staged(tmp_path / "cal.json", kind="file", siblings=("cal.",)).check()
    Staged(tmp_path / "empty").check()  # an empty folder is not used
    Staged(tmp_path / "run", overwrite=True).check()
    Staged(tmp_path / "file", overwrite=True, kind="file").check()


def test_outputs_replace_the_earlier_ones_only_when_complete(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "old.csv").write_text("old")
    (out / "vtu").mkdir()
    with pytest.raises(RuntimeError, match="part way"):
        with Staged(out, overwrite=True) as st:
            (st.path / "new.csv").write_text("new")
            assert names(out) == ["old.csv", "vtu"]  # intact while the run writes
            raise RuntimeError("failed part way")
    assert names(out) == ["old.csv", "vtu"] and names(tmp_path) == ["run", "run/old.csv", "run/vtu"]
    with Staged(out, overwrite=True) as st:
        (st.path / "new.csv").write_text("new")
        assert st.shown(f"-> {st.path / 'new.csv'}") == f"-> {out / 'new.csv'}"
    assert names(tmp_path) == ["run", "run/new.csv"]  # the earlier outputs all gone
    # a file and its companions: each moved beside --out
    with Staged(tmp_path / "c" / "cal.json", kind="file", siblings=("cal.",)) as st:
        st.path.write_text("{}")
        (st.path.parent / "cal.ingest").mkdir()
        (st.path.parent / "cal.ingest" / "shard.npz").write_text("")
    assert names(tmp_path / "c") == ["cal.ingest", "cal.ingest/shard.npz", "cal.json"]
    # a run that fails in a folder it made leaves no folder
    with pytest.raises(KeyboardInterrupt):
        with Staged(tmp_path / "a" / "b" / "out"):
            raise KeyboardInterrupt
    assert not (tmp_path / "a").exists()


def test_a_signal_in_a_held_block_is_raised_after_it():
    done = []
    with catch_signals() as caught:
        with pytest.raises(KeyboardInterrupt):
            with held():
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(0.05)
                done.append("held block completed")
    assert done == ["held block completed"] and caught.signum == signal.SIGTERM


_IN_A_CALLBACK = """
import ctypes, os, signal, sys
from finray.outputs import Staged, catch_signals

def stop(signum):
    sys.stderr.write("stopped\\n")
    os._exit(128 + signum)

with catch_signals(stop if sys.argv[2] == "stop" else None):
    with Staged(sys.argv[1]) as st:
        (st.path / "half.csv").write_text("half")

        def compare(a, b):  # Python that C calls back (as torch's pybind11, llvmlite's ctypes)
            os.kill(os.getpid(), signal.SIGINT)
            sum(range(10000))  # bytecode: the handler runs here, inside the callback
            return 0

        CMP = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)
        values = (ctypes.c_int * 2)(2, 1)
        ctypes.CDLL(None).qsort(values, 2, ctypes.sizeof(ctypes.c_int), CMP(compare))
print("the signal was lost")
"""


def test_the_commands_process_stops_where_a_signal_comes_even_in_a_callback(tmp_path):
    """A KeyboardInterrupt raised in Python code that C calls back is dropped by ctypes
    (the run went on, exit 0) and aborts the process through pybind11 (CI: -6): in the
    command's process (``catch_signals(stop)``) the signal removes the temporary folder
    and ends the process where it comes."""

    def run(mode):
        return subprocess.run(
            [sys.executable, "-c", _IN_A_CALLBACK, str(tmp_path / mode), mode],
            capture_output=True,
            text=True,
            timeout=60,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )

    p = run("stop")
    assert (p.returncode, p.stdout, p.stderr) == (130, "", "stopped\n")
    assert names(tmp_path) == []  # no --out, no <out>.part-<pid>
    p = run("raise")  # what a raised KeyboardInterrupt does there (why stop exists)
    assert p.returncode == 0 and "the signal was lost" in p.stdout, p


def test_calibrate_refuses_an_out_that_exists_or_is_a_folder(tmp_path, capsys):
    """--out an existing file (was overwritten, exit 0) or a folder (IsADirectoryError):
    one line, exit code 2, nothing touched."""
    (tmp_path / "cal.json").write_text("mine")
    (tmp_path / "folder").mkdir()
    argv = ["calibrate", str(tmp_path / "take"), "--model", str(tmp_path / "model.pt")]
    assert main([*argv, "--out", str(tmp_path / "cal.json")]) == 2
    assert "cal.json exists (1: cal.json); give --overwrite" in one_line(
        capsys, "finray calibrate: "
    )
    assert main([*argv, "--out", str(tmp_path / "folder")]) == 2
    assert "folder is a folder, not a file" in one_line(capsys, "finray calibrate: ")
    assert (tmp_path / "cal.json").read_text() == "mine"
    assert names(tmp_path) == ["cal.json", "folder"]


def test_ingest_refuses_a_used_out_and_replaces_an_earlier_run_whole(tmp_path, capsys):
    """--out an existing file (was FileExistsError), a path that cannot be made (was
    FileNotFoundError), an earlier run's folder (its old files were left beside the new);
    --overwrite replaces the folder whole, once the new outputs are complete."""
    write_take(tmp_path / "take", **SMALL_TAKE)
    take = str(tmp_path / "take")
    (tmp_path / "file").write_text("mine")
    assert main(["ingest", take, "--out", str(tmp_path / "file")]) == 2
    assert "file is a file, not a folder" in one_line(capsys, "finray ingest: ")
    assert main(["ingest", take, "--out", "/proc/finray_x"]) == 2
    assert "--out /proc/finray_x cannot be created (" in one_line(capsys, "finray ingest: ")
    out = tmp_path / "out"
    out.mkdir()
    (out / "stale.txt").write_text("an earlier run's")
    assert main(["ingest", take, "--out", str(out)]) == 2
    assert "holds another run's results (1: stale.txt)" in one_line(capsys, "finray ingest: ")
    # a take that cannot be ingested, with --overwrite: the earlier run stays
    (tmp_path / "bad").mkdir()
    assert main(["ingest", str(tmp_path / "bad"), "--out", str(out), "--overwrite"]) == 2
    capsys.readouterr()
    assert names(out) == ["stale.txt"]
    assert main(["ingest", take, "--out", str(out), "--overwrite"]) == 0
    log = capsys.readouterr().out
    assert f"-> {out / 'shard.npz'}" in log and ".part-" not in log
    assert names(out) == ["frames.csv", "ingest.json", "qa.png", "shard.npz", "sync.json"]
    assert [p.name for p in tmp_path.iterdir() if ".part-" in p.name] == []


def test_predict_overwrite_with_an_unreadable_input_keeps_the_earlier_run(
    small_model, render_png, tmp_path, capsys
):
    """It deleted the earlier files first and left the folder empty."""
    out = tmp_path / "out"
    argv = ["predict", "--model", str(small_model), "--out", str(out), "--backend", "torchscript"]
    assert main([*argv, str(render_png)]) == 0
    first = {p: p.read_bytes() for p in out.iterdir()}
    capsys.readouterr()
    bad = tmp_path / "bad.png"
    bad.write_text("not an image")
    assert main([*argv, str(bad), "--overwrite"]) == 2
    assert "bad.png: not a readable image" in one_line(capsys, "finray predict: ")
    assert {p: p.read_bytes() for p in out.iterdir()} == first
    # the same run again, --overwrite: the same files, byte for byte (the segmentation's
    # JSON and the stress maps)
    assert main([*argv, str(render_png), "--overwrite"]) == 0
    again = {p: p.read_bytes() for p in out.iterdir()}
    assert sorted(again) == sorted(first)
    assert again[out / "forces.csv"] == first[out / "forces.csv"]


# -- signals: subprocesses sent SIGINT / SIGTERM part way --------------------------------


def _complete_or_none(args, out: Path, tmp_path):
    """Run ``args`` uninterrupted (the reference: its outputs and wall time), then three
    times, each sent a signal at a point of its run (as it loads its modules, part way,
    near the end): --out complete or absent, one line."""
    import shutil

    t0 = time.perf_counter()
    p = start_finray(args, tmp_path)
    _, err = p.communicate(timeout=120)
    wall_s = time.perf_counter() - t0
    assert p.returncode == 0, err
    reference = names(out)
    shutil.rmtree(out)
    command, stopped = args[0], 0
    for delay, sig in [
        (max(0.8, 0.2 * wall_s), "INT"),
        (0.5 * wall_s, "TERM"),
        (0.85 * wall_s, "INT"),
    ]:
        p = start_finray(args, tmp_path)
        time.sleep(delay)
        signum = getattr(signal, f"SIG{sig}")
        p.send_signal(signum)
        _, err = p.communicate(timeout=120)
        assert "Traceback" not in err, err
        if p.returncode == 0:  # done before the signal came
            assert names(out) == reference
        else:
            what = "interrupted" if sig == "INT" else "terminated"
            assert p.returncode == 128 + signum, (p.returncode, err)
            stopped += 1
            last = err.strip().splitlines()[-1]
            assert last == f"finray {command}: {what}; nothing written", err
            assert not out.exists()
        assert [p.name for p in out.parent.iterdir() if ".part-" in p.name] == []
        if out.exists():
            import shutil

            shutil.rmtree(out)
    assert stopped >= 2  # the signals came while it ran


@pytest.mark.slow
def test_a_signal_during_ingest_leaves_the_outputs_complete_or_none(tmp_path):
    """SIGTERM left a 0-byte shard.npz; Ctrl-C right after sync.json an ImportError."""
    write_take(tmp_path / "take", **SMALL_TAKE)
    out = tmp_path / "out"
    args = ["ingest", str(tmp_path / "take"), "--out", str(out)]
    _complete_or_none(args, out, tmp_path)


@pytest.mark.slow
def test_a_signal_during_predict_leaves_the_outputs_complete_or_none(
    small_model, render_png, tmp_path
):
    """SIGTERM left forces.csv.part behind."""
    frames = tmp_path / "frames"
    frames.mkdir()
    for k in range(12):
        (frames / f"f{k:02d}.png").write_bytes(render_png.read_bytes())
    out = tmp_path / "out"
    args = ["predict", "--model", str(small_model), str(frames), "--out", str(out)]
    args += ["--backend", "torchscript"]
    _complete_or_none(args, out, tmp_path)


@pytest.mark.slow
def test_simulate_replaces_an_earlier_run_whole_and_sigterm_leaves_none(tmp_path):
    """simulate into an earlier run's folder kept its finger.pvd and vtu/ beside the new
    files; SIGTERM part way left a truncated result.npz."""
    out = tmp_path / "out"
    (out / "vtu").mkdir(parents=True)
    (out / "finger.pvd").write_text("an earlier run's")
    scene = ["simulate", "--object", "circle", "--size-mm", "20", "--height-mm", "30"]
    args = [*scene, "--mesh-size-mm", "3", "--no-vtu", "--out", str(out)]
    r = subprocess.run([sys.executable, "-m", "finray.cli", *args], capture_output=True, text=True)
    assert r.returncode == 2 and "holds another run's results (2: finger.pvd, vtu)" in r.stderr
    p = start_finray([*args, "--overwrite"], tmp_path)
    err = ""
    while "frame" not in err:  # the solver's first progress line: it is simulating
        line = p.stderr.readline()
        assert line, "simulate ended before its first frame"
        err += line
    p.send_signal(signal.SIGTERM)
    _, rest = p.communicate(timeout=60)
    assert p.returncode == 143 and "Traceback" not in rest
    assert rest.strip().splitlines()[-1] == "finray simulate: terminated; nothing written"
    assert names(out) == ["finger.pvd", "vtu"]  # the earlier run, intact
    r = subprocess.run(
        [sys.executable, "-m", "finray.cli", *args, "--overwrite"], capture_output=True, text=True
    )
    assert r.returncode == 0, r.stderr
    assert names(out) == ["forces.csv", "result.npz", "summary.json"]
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


@pytest.mark.slow
def test_a_signal_while_the_command_starts_is_one_line(tmp_path):
    """Before finray.cli.main catches signals (its modules still loading), a SIGINT or
    SIGTERM ends the command in one line too (finray._start, installed first by
    finray/__init__); only one in Python's own start, before finray's first line, ends
    it as Python does (SIGTERM silently, SIGINT with a KeyboardInterrupt in no finray
    file). Nothing is written either way."""
    out = tmp_path / "out"
    args = ["simulate", "--object", "circle", "--size-mm", "20", "--height-mm", "30"]
    args += ["--mesh-size-mm", "3", "--no-vtu", "--out", str(out)]
    handled = 0
    for delay in (0.05, 0.1, 0.2):
        for sig in (signal.SIGINT, signal.SIGTERM):
            p = start_finray(args, tmp_path)
            time.sleep(delay)
            p.send_signal(sig)
            _, err = p.communicate(timeout=60)
            what = "interrupted" if sig == signal.SIGINT else "terminated"
            if "KeyboardInterrupt" in err and "finray" not in err:  # SIGINT in Python's start
                # (Python 3.8+ ends on it by SIGINT itself: -2, a traceback of runpy frames)
                assert sig == signal.SIGINT and p.returncode in (1, -sig)
            elif p.returncode == -sig:  # SIGTERM in Python's own start
                assert sig == signal.SIGTERM and err == ""
            else:
                assert (p.returncode, err) == (
                    128 + sig,
                    f"finray simulate: {what}; nothing written\n",
                )
                handled += 1
            assert not out.exists() and list(tmp_path.iterdir()) == []
    assert handled >= 4


def test_overwrite_never_removes_an_input_or_the_current_folder(tmp_path, monkeypatch, capsys):
    """``ingest take --out take --overwrite`` would have replaced the take by its shard."""
    write_take(tmp_path / "take", **SMALL_TAKE)
    before = names(tmp_path / "take")
    for out in [tmp_path / "take", tmp_path]:
        assert main(["ingest", str(tmp_path / "take"), "--out", str(out), "--overwrite"]) == 2
        assert f"--out {out} holds the input {tmp_path / 'take'}: --overwrite would remove it" in (
            one_line(capsys, "finray ingest: ")
        )
    (tmp_path / "here").mkdir()
    (tmp_path / "here" / "x").write_text("")
    monkeypatch.chdir(tmp_path / "here")
    with pytest.raises(UsageError, match="holds the current folder"):
        Staged(".", overwrite=True).check()
    cal = Staged(tmp_path / "model.pt", overwrite=True, kind="file", inputs=["model.pt"])
    (tmp_path / "model.pt").write_text("")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(UsageError, match="holds the input model.pt"):
        cal.check()
    assert names(tmp_path / "take") == before


def test_an_error_that_a_signal_caused_is_an_interruption(tmp_path, monkeypatch, capsys):
    """Ctrl-C in an import gave ``ImportError: initialization failed``: the signal, not
    the error it caused, is what the line reports (SIGTERM here, as SIGINT)."""
    import finray.recording

    def cut_short(*args, **kwargs):
        try:
            os.kill(os.getpid(), signal.SIGTERM)  # (a pytest-xdist worker ignores SIGINT)
            time.sleep(1)
        except KeyboardInterrupt:
            raise ImportError("initialization failed") from None

    monkeypatch.setattr(finray.recording, "ingest", cut_short)
    assert main(["ingest", str(tmp_path), "--out", str(tmp_path / "out")]) == 143
    assert one_line(capsys, "finray ingest: ") == "finray ingest: terminated; nothing written"
    assert names(tmp_path) == []
