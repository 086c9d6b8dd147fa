"""The doors of issue 67: a model's settings (``model.ts.json``) checked by a schema and
by their own seal, every path a take names confined to its folder, take.json's numbers
range-checked, ``--out`` at its edges and a colour range of the wrong shape: each
refused in one line, exit code 2, nothing written."""

import json
import os
import shutil
from pathlib import Path

import pytest

from finray.cli import main

from recording_synth import write_take

SMALL_TAKE = dict(size=(320, 240), duration_s=2.5, starts=(0.3, 1.35), ramp=0.35, hold=0.2)


def one_line(capsys, prefix: str) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith(f"{prefix}note:")]
    assert len(lines) == 1 and lines[0].startswith(prefix) and "Traceback" not in err, err
    return lines[0]


@pytest.fixture(scope="module")
def model(small_model):
    """The folder of conftest's small exported model."""
    return small_model.parent


def _with(model_dir: Path, tmp_path: Path, change, reseal: bool) -> Path:
    """A copy of the model whose settings ``change`` edits; resealed (a malformed export)
    or not (a file edited after its export)."""
    from finray.train.export import seal

    d = tmp_path / "m"
    shutil.copytree(model_dir, d)
    meta = json.loads((d / "model.ts.json").read_text())
    change(meta)
    (d / "model.ts.json").write_text(json.dumps(meta))
    if reseal:
        seal(d / "model.ts")
    return d / "model.ts"


def _set(path, value):
    def change(meta):
        *up, key = path
        node = meta
        for k in up:
            node = node[k]
        node[key] = value

    return change


MALFORMED = {
    "NaN crop": (_set(("preprocess", "crop_x_mm"), [float("nan"), 35.0]), "not finite"),
    "inverted crop": (_set(("preprocess", "crop_y_mm"), [80.0, 0.0]), "lo above hi"),
    "string base width": (_set(("preprocess", "base_width_mm"), "30"), "is not of type"),
    "garbage trained": (_set(("trained",), "everything"), "is not of type 'object'"),
    "unknown segmentation key": (
        _set(("preprocess", "segment", "thresold"), "otsu"),
        "Additional properties are not allowed",
    ),
    "huge input": (_set(("height",), 2**30), "is greater than the maximum"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_settings_are_one_line(model, tmp_path, capsys, render_png, case):
    change, words = MALFORMED[case]
    ts = _with(model, tmp_path, change, reseal=True)
    out = tmp_path / "out"
    assert main(["predict", "--model", str(ts), str(render_png), "--out", str(out)]) == 2
    msg = one_line(capsys, "finray predict: ")
    assert "model.ts.json is not a model's settings (" in msg and words in msg, msg
    assert not out.exists() and not list(tmp_path.glob("out.part-*"))


def test_settings_edited_after_their_export_are_refused(model, tmp_path, capsys, render_png):
    """A value changed in a sealed file (here the base width the crop is scaled by):
    its own SHA-256 no longer holds."""
    ts = _with(model, tmp_path, _set(("preprocess", "base_width_mm"), 25.0), reseal=False)
    out = tmp_path / "out"
    assert main(["predict", "--model", str(ts), str(render_png), "--out", str(out)]) == 2
    assert "model.ts.json was changed since its export" in one_line(capsys, "finray predict: ")
    assert not out.exists()


def test_a_sealed_export_reads_and_a_reindented_one_too(model, tmp_path):
    from finray.train.settings import read_settings

    meta, note = read_settings(model / "model.ts.json")
    assert note is None and "settings" in meta["sha256"]
    (tmp_path / "model.ts.json").write_text(json.dumps(meta, indent=4, sort_keys=True))
    assert read_settings(tmp_path / "model.ts.json")[1] is None


@pytest.mark.parametrize("where", ["absolute", "up", "link"])
def test_a_take_s_frames_are_files_of_its_folder(tmp_path, capsys, where):
    """frames.csv naming an image outside frames/ (was read wherever it was)."""
    write_take(tmp_path / "take", kind="frames", **SMALL_TAKE)
    outside = tmp_path / "elsewhere.png"
    frames = tmp_path / "take" / "frames"
    first = sorted(frames.iterdir())[0]
    shutil.copy(first, outside)
    csv = tmp_path / "take" / "frames.csv"
    lines = csv.read_text().splitlines()
    name = lines[1].split(",")[0]
    if where == "absolute":
        new = str(outside)
    elif where == "up":
        new = "../../elsewhere.png"
    else:
        os.remove(frames / name)
        os.symlink(outside, frames / name)
        new = name
    lines[1] = ",".join([new, *lines[1].split(",")[1:]])
    csv.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    assert main(["ingest", str(tmp_path / "take"), "--out", str(out)]) == 2
    msg = one_line(capsys, "finray ingest: ")
    assert "frames.csv: frame" in msg and "is not a file in" in msg
    assert not out.exists()


def test_a_take_s_video_link_out_of_its_folder_is_refused(tmp_path, capsys):
    write_take(tmp_path / "take", **SMALL_TAKE)
    take = tmp_path / "take"
    video = next(take.glob("*.mp4"))
    moved = tmp_path / "elsewhere.mp4"
    video.rename(moved)
    os.symlink(moved, take / "link.mp4")
    meta = json.loads((take / "take.json").read_text())
    (take / "take.json").write_text(json.dumps({**meta, "video": "link.mp4"}))
    assert main(["ingest", str(take), "--out", str(tmp_path / "out")]) == 2
    assert "video: 'link.mp4' is not a file in the take's own folder" in one_line(
        capsys, "finray ingest: "
    )


@pytest.mark.parametrize(
    "field,value,words",
    [
        ("contact_height_mm", 1e300, "contact_height_mm: 1e+300 is greater than the maximum"),
        ("camera", {"px_per_mm": 1e12}, "camera/px_per_mm: 1000000000000.0 is greater than"),
        ("camera", {"intrinsics": {"fx": -5, "fy": 900, "cx": 1, "cy": 1}}, "fx: -5 is less"),
    ],
)
def test_take_json_numbers_are_range_checked(tmp_path, capsys, field, value, words):
    write_take(tmp_path / "take", **SMALL_TAKE)
    path = tmp_path / "take" / "take.json"
    path.write_text(json.dumps({**json.loads(path.read_text()), field: value}))
    assert main(["ingest", str(tmp_path / "take"), "--out", str(tmp_path / "out")]) == 2
    msg = one_line(capsys, "finray ingest: ")
    assert words in msg, msg
    assert not (tmp_path / "out").exists()


SCENE = ["--object", "circle", "--size-mm", "20", "--height-mm", "30"]
COMMANDS = {
    "geometry": lambda tmp, model, png: ["geometry", *SCENE],
    "simulate": lambda tmp, model, png: ["simulate", *SCENE],
    "ingest": lambda tmp, model, png: ["ingest", str(tmp / "take")],
    "predict": lambda tmp, model, png: ["predict", "--model", str(model / "model.ts"), str(png)],
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_out_edges_are_one_line_before_any_work(
    model, render_png, tmp_path, capsys, command, monkeypatch
):
    """--out a link to a folder, a name past the file system's limit, and a used folder
    that cannot be moved aside (were tracebacks, the last at the end of the work)."""
    if command == "ingest":
        write_take(tmp_path / "take", **SMALL_TAKE)
    argv = COMMANDS[command](tmp_path, model, render_png)
    prefix = f"finray {command}: "
    (tmp_path / "real").mkdir()
    os.symlink(tmp_path / "real", tmp_path / "link")
    assert main([*argv, "--out", str(tmp_path / "link")]) == 2
    assert "--out" in (msg := one_line(capsys, prefix)) and "is a symbolic link" in msg
    assert main([*argv, "--out", str(tmp_path / ("x" * 250))]) == 2
    assert "--out name is 250 bytes long; at most" in one_line(capsys, prefix)
    used = tmp_path / "used"
    used.mkdir()
    (used / "old.txt").write_text("an earlier run's")
    real_access = os.access
    monkeypatch.setattr(
        os, "access", lambda p, m: False if Path(p) == used else real_access(p, m)
    )  # as a user without write permission on it (root has every permission)
    assert main([*argv, "--out", str(used), "--overwrite"]) == 2
    assert "cannot be moved aside to be replaced" in one_line(capsys, prefix)
    assert sorted(p.name for p in tmp_path.iterdir() if "part-" in p.name) == []
    assert (used / "old.txt").read_text() == "an earlier run's"


def test_a_move_the_file_system_refuses_keeps_the_outputs(tmp_path, monkeypatch):
    """The outputs are complete when they are moved into place: a refusal there is one
    line that says where they are."""
    from finray.errors import UsageError
    from finray.outputs import Staged

    out = tmp_path / "run"
    staged = Staged(out)
    staged.open()
    (staged.path / "a.csv").write_text("done")

    def refuse(src, dest):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(
        UsageError, match=r"could not be moved into place \(Permission denied\); they are kept in"
    ):
        staged.commit()
    assert (staged.tmp / "a.csv").read_text() == "done"


@pytest.mark.parametrize(
    "spec,words",
    [
        ('{"space": "hsv", "lo": [10], "hi": [40, 1, 1]}', "lo must be three finite numbers"),
        ('{"space": "rgb", "lo": [0, 0, 0], "hi": [1, 1, 1]}', "colour space 'rgb' is not one of"),
        ('{"space": "hsv", "lo": [0, 0.9, 0], "hi": [40, 0.2, 1]}', "is above hi"),
    ],
)
def test_a_finger_colour_of_the_wrong_shape_is_one_line(
    model, tmp_path, capsys, render_png, spec, words
):
    """A colour range file with too few values (was IndexError), an unknown space, lo
    above hi."""
    f = tmp_path / "colour.json"
    f.write_text(spec)
    out = tmp_path / "out"
    argv = ["predict", "--model", str(model / "model.ts"), str(render_png), "--out", str(out)]
    assert main([*argv, "--finger-colour", str(f)]) == 2
    msg = one_line(capsys, "finray predict: ")
    assert words in msg, msg
    assert not out.exists()
