"""The finray command line."""
import subprocess
import sys

import numpy as np
import pytest

from finray.cli import build_parser
from finray.geometry.mesh import TriMesh


def run(*args):
    return subprocess.run([sys.executable, "-m", "finray.cli", *args], capture_output=True, text=True)


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
    r = run("geometry", "--object", "circle", "--size-mm", "20", "--height-mm", "30",
            "--out", str(tmp_path), "--plot", "--mesh-size-mm", "1.0")
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
    r = run("geometry", "--object-file", str(f), "--height-mm", "20", "--out", str(tmp_path / "o"),
            "--deformable", "--mesh-size-mm", "1.0")
    assert r.returncode == 0, r.stderr
    obj = TriMesh.load(tmp_path / "o" / "objects" / "part_h20.npz")
    assert len(obj.triangles) > 0 and np.isfinite(obj.points).all()


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
    r = run(command, "--config", str(missing), "--object", "circle", "--size-mm", "20",
            "--height-mm", "30", "--out", str(tmp_path / "out"))
    msg = one_line_error(r, f"finray {command}: config error: ")
    assert f"config file '{missing}' does not exist" in msg
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("text, why", [("finger: [1, 2\n  mesh: {", "is not valid YAML"),
                                       ("- a list\n- of things\n", "is not a mapping")])
def test_config_that_is_not_a_mapping_is_an_error(tmp_path, text, why):
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    r = run("geometry", "--config", str(bad), "--out", str(tmp_path / "out"))
    assert why in one_line_error(r, "finray geometry: config error: ")
