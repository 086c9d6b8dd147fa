"""The finray command line."""

import subprocess
import sys

import numpy as np
import pytest

from finray.cli import build_parser
from finray.geometry.mesh import TriMesh

pytestmark = pytest.mark.slow  # not in `pytest -m "not slow"`


def run(*args):
    return subprocess.run(
        [sys.executable, "-m", "finray.cli", *args], capture_output=True, text=True
    )


def test_help_lists_every_option_with_units():
    r = run("--help")
    assert r.returncode == 0 and "geometry" in r.stdout
    r = run("geometry", "--help")
    assert r.returncode == 0
    parser = build_parser()
    for name, sub in parser._subparsers._group_actions[0].choices.items():
        for action in sub._actions:
            assert action.help, f"finray {name}: option {action.option_strings} has no help"
            if action.dest.endswith("_mm"):
                assert "mm" in action.help, (name, action.dest)
            if action.dest.endswith("_deg"):
                assert "deg" in action.help, (name, action.dest)


def test_geometry_one_object(tmp_path):
    r = run(
        "geometry",
        "--object",
        "circle",
        "--size-mm",
        "20",
        "--height-mm",
        "30",
        "--out",
        str(tmp_path),
        "--plot",
        "--mesh-size-mm",
        "1.0",
    )
    assert r.returncode == 0, r.stderr
    obj = TriMesh.load(tmp_path / "objects" / "circle_20mm_h30.npz")
    assert obj.meta["reference_point_mm"][1] == 30.0
    assert len(obj.triangles) == 0
    finger = TriMesh.load(tmp_path / "finger.npz")
    assert finger.meta["size_mm"] == 1.0
    assert (tmp_path / "objects" / "circle_20mm_h30.png").stat().st_size > 0
    assert (tmp_path / "finger_surface.ply").stat().st_size > 0


def test_geometry_object_file(tmp_path):
    f = tmp_path / "part.json"
    f.write_text("[[-4, -4], [5, -3], [1, 6]]")
    r = run(
        "geometry",
        "--object-file",
        str(f),
        "--height-mm",
        "20",
        "--out",
        str(tmp_path / "o"),
        "--deformable",
        "--mesh-size-mm",
        "1.0",
    )
    assert r.returncode == 0, r.stderr
    obj = TriMesh.load(tmp_path / "o" / "objects" / "part_h20.npz")
    assert len(obj.triangles) > 0 and np.isfinite(obj.points).all()


def test_geometry_fractional_size_and_odd_file_name(tmp_path):
    """A size in tenths of a mm and a file name with a space and dots make valid names."""
    r = run(
        "geometry",
        "--object",
        "square",
        "--size-mm",
        "16.5",
        "--angle-deg",
        "-7.5",
        "--height-mm",
        "30",
        "--out",
        str(tmp_path / "s"),
        "--mesh-size-mm",
        "1.0",
    )
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "s" / "objects" / "square_16p5mm_a-7p5_h30.npz").is_file()
    f = tmp_path / "my part.v2.json"
    f.write_text("[[-4, -4], [5, -3], [1, 6]]")
    r = run(
        "geometry",
        "--object-file",
        str(f),
        "--height-mm",
        "20",
        "--out",
        str(tmp_path / "o"),
        "--mesh-size-mm",
        "1.0",
    )
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "o" / "objects" / "my_part_v2_h20.npz").is_file()


def one_line_error(r, prefix):
    """Exit code 2, nothing on stdout, one line on stderr that starts with ``prefix``."""
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(prefix), r.stderr
    return lines[0]


@pytest.mark.parametrize("command", ["geometry", "simulate"])
def test_missing_size_is_an_error_named_by_its_command(tmp_path, command):
    extra = ["--height-mm", "30"] if command == "simulate" else []
    r = run(command, "--object", "square", *extra, "--out", str(tmp_path))
    msg = one_line_error(r, f"finray {command}: ")
    assert "--size-mm is required with --object" in msg


def test_simulate_without_an_object_is_an_error(tmp_path):
    r = run("simulate", "--height-mm", "30", "--out", str(tmp_path))
    assert "give --object or --object-file" in one_line_error(r, "finray simulate: ")


@pytest.mark.parametrize("command", ["geometry", "simulate"])
def test_missing_config_file_is_an_error(tmp_path, command):
    """A --config that does not exist stops the command (it once ran on the defaults)."""
    missing = tmp_path / "missing.yaml"
    r = run(
        command,
        "--config",
        str(missing),
        "--object",
        "circle",
        "--size-mm",
        "20",
        "--height-mm",
        "30",
        "--out",
        str(tmp_path / "out"),
    )
    msg = one_line_error(r, f"finray {command}: config error: ")
    assert f"config file '{missing}' does not exist" in msg
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "text, why",
    [
        ("finger: [1, 2\n  mesh: {", "is not valid YAML"),
        ("- a list\n- of things\n", "is not a mapping"),
    ],
)
def test_config_that_is_not_a_mapping_is_an_error(tmp_path, text, why):
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    r = run("geometry", "--config", str(bad), "--out", str(tmp_path / "out"))
    assert why in one_line_error(r, "finray geometry: config error: ")


@pytest.mark.parametrize(
    "option, value",
    [
        ("--size-mm", "0"),
        ("--minor-mm", "0"),
        ("--mesh-size-mm", "0"),
        ("--size-mm", "-5"),
        ("--wall-mm", "nan"),
    ],
)
def test_sizes_of_zero_or_below_are_refused(tmp_path, option, value):
    """A size of 0 once silently took the default (a truthiness test)."""
    args = {"--size-mm": "16", "--minor-mm": "9", "--mesh-size-mm": "1.0", "--wall-mm": "2"} | {
        option: value
    }
    r = run(
        "simulate",
        "--object",
        "ellipse",
        *sum(([k, v] for k, v in args.items()), []),
        "--height-mm",
        "30",
        "--out",
        str(tmp_path / "out"),
    )
    expected = (
        f"{option} must be a finite number of mm, got nan"
        if value == "nan"
        else f"{option} must be > 0 mm, got {value}"
    )
    assert expected in one_line_error(r, "finray simulate: ")
    assert not (tmp_path / "out").exists()


def test_simulate_refuses_two_heights(tmp_path):
    r = run(
        "simulate",
        "--object",
        "circle",
        "--size-mm",
        "20",
        "--height-mm",
        "20",
        "--height-mm",
        "30",
        "--out",
        str(tmp_path / "out"),
    )
    msg = one_line_error(r, "finray simulate: ")
    assert "--height-mm takes one height, got 2 (20, 30)" in msg
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["geometry", "simulate"])
def test_an_out_that_is_a_file_or_cannot_be_created_is_refused(tmp_path, command):
    (tmp_path / "taken").write_text("a file")
    base = [
        command,
        "--object",
        "circle",
        "--size-mm",
        "20",
        "--height-mm",
        "30",
        "--mesh-size-mm",
        "3",
    ]
    r = run(*base, "--out", str(tmp_path / "taken"))
    assert f"--out {tmp_path / 'taken'} is a file, not a folder" in one_line_error(
        r, f"finray {command}: "
    )
    assert (tmp_path / "taken").read_text() == "a file"
    r = run(*base, "--out", str(tmp_path / "taken" / "sub"))
    assert f"--out {tmp_path / 'taken' / 'sub'} cannot be created (" in one_line_error(
        r, f"finray {command}: "
    )


def test_predict_refuses_zero_threads_and_an_out_that_is_a_file(tmp_path):
    (tmp_path / "taken").write_text("a file")
    r = run(
        "predict",
        "--model",
        str(tmp_path / "m.ts"),
        str(tmp_path),
        "--threads",
        "0",
        "--out",
        str(tmp_path / "o"),
    )
    assert "--threads must be between 1 and " in one_line_error(r, "finray predict: ")
    r = run(
        "predict",
        "--model",
        str(tmp_path / "m.ts"),
        str(tmp_path),
        "--out",
        str(tmp_path / "taken"),
    )
    assert "is a file, not a folder" in one_line_error(r, "finray predict: ")


@pytest.mark.parametrize(
    "kind, why",
    [
        ("folder", "is a folder, not a config file"),
        ("latin1", "is not UTF-8 text (byte "),
        ("empty", "is empty: give the config's keys"),
    ],
)
def test_config_that_is_a_folder_not_utf8_or_empty_is_an_error(tmp_path, kind, why):
    bad = tmp_path / "bad.yaml"
    if kind == "folder":
        bad.mkdir()
    else:
        bad.write_bytes("finger: {material: \xe9}\n".encode("latin-1") if kind == "latin1" else b"")
    r = run("geometry", "--config", str(bad), "--out", str(tmp_path / "out"))
    assert why in one_line_error(r, "finray geometry: config error: ")
    assert not (tmp_path / "out").exists()


def test_ctrl_c_during_simulate_is_one_line(tmp_path):
    """SIGINT part way through a simulation: one line and exit code 130, no traceback."""
    import signal
    import time

    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "finray.cli",
            "simulate",
            "--object",
            "circle",
            "--size-mm",
            "20",
            "--height-mm",
            "30",
            "--no-vtu",
            "--out",
            str(tmp_path / "out"),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # a worker of pytest-xdist ignores SIGINT, and a child inherits that
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    err = ""
    while "frame" not in err:  # the solver's first progress line: it is simulating
        line = p.stderr.readline()
        assert line, "simulate ended before its first frame"
        err += line
    time.sleep(0.5)
    p.send_signal(signal.SIGINT)
    out, rest = p.communicate(timeout=60)
    assert p.returncode == 130
    lines = [ln for ln in rest.strip().splitlines() if ln]
    assert lines == ["finray simulate: interrupted; nothing written"], rest
    assert not (tmp_path / "out").exists() and not list(tmp_path.glob("out.part-*"))


def test_predict_help_examples_parse():
    """Each example of ``finray predict --help`` is a command the parser takes."""
    import shlex

    from finray.cli import PREDICT_HELP

    examples = [
        line.strip()
        for line in PREDICT_HELP.split("examples:")[1].splitlines()
        if line.strip().startswith("finray predict")
    ]
    assert len(examples) >= 3
    for line in examples:
        args = build_parser().parse_args(shlex.split(line)[1:])
        assert args.command == "predict" and args.out is not None
