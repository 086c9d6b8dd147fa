"""One home for the package's exceptions (finray.errors), one base (FinrayError), and
the CLI's exit codes: 2 for bad input, 1 for work that failed part way."""

import ast
import inspect
from pathlib import Path

import numpy as np

import finray
from finray import errors
from finray.cli import main

SRC = Path(finray.__file__).parent
ROOT = SRC.parents[1]


def test_every_exception_is_a_finray_error_and_keeps_its_builtin_kind():
    classes = [
        c
        for _, c in inspect.getmembers(errors, inspect.isclass)
        if issubclass(c, BaseException) and c.__module__ == errors.__name__
    ]
    assert len(classes) > 10 and all(issubclass(c, errors.FinrayError) for c in classes)
    # code that catches the builtin kinds keeps working
    assert issubclass(errors.ConfigError, ValueError)
    assert issubclass(errors.SimulationError, RuntimeError)
    assert issubclass(errors.NotPositiveDefinite, np.linalg.LinAlgError)
    assert issubclass(errors.StabilityFailure, AssertionError)
    assert not issubclass(errors.SimulationError, errors.BadInput)


def test_no_other_module_defines_an_exception():
    defined = []
    for path in sorted(SRC.rglob("*.py")):
        if path == SRC / "errors.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef) and any(
                ast.unparse(b).split(".")[-1].endswith(("Error", "Exception", "Failure"))
                for b in node.bases
            ):
                defined.append(f"{path.relative_to(SRC)}: {node.name}")
    assert not defined, "exceptions belong in finray/errors.py: " + ", ".join(defined)


def test_a_failed_scene_exits_with_1_and_one_line(tmp_path, monkeypatch, capsys):
    import finray.fea.scene

    def fail(*args, **kwargs):
        raise errors.SimulationError("load step 3 failed: line search failed", step=3)

    monkeypatch.setattr(finray.fea.scene, "run_scene", fail)
    code = main(
        [
            "simulate",
            "--config",
            str(ROOT / "config" / "smoke.yaml"),
            "--object",
            "circle",
            "--size-mm",
            "10",
            "--height-mm",
            "30",
            "--out",
            str(tmp_path / "c10"),
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert err[-1] == "finray simulate: load step 3 failed: line search failed"


def test_bad_input_exits_with_2(tmp_path, capsys):
    assert main(["simulate", "--height-mm", "30", "--out", str(tmp_path)]) == 2
    assert capsys.readouterr().err.strip() == "finray simulate: give --object or --object-file"


def test_the_fea_raises_the_errors_of_the_one_home():
    import finray.fea
    import finray.fea.linear

    assert finray.fea.SimulationError is errors.SimulationError
    assert finray.fea.linear.NotPositiveDefinite is errors.NotPositiveDefinite


def test_an_unknown_material_names_the_flag_and_the_choices(tmp_path, capsys):
    argv = ["simulate", "--object", "circle", "--size-mm", "20", "--height-mm", "30"]
    assert main([*argv, "--material", "unobtainium", "--out", str(tmp_path / "o")]) == 2
    from finray.config import default_config_path, read_config_file

    known = ", ".join(sorted(read_config_file(default_config_path())["materials"]))
    err = capsys.readouterr().err.strip()
    assert err == (
        f"finray simulate: --material unobtainium: not a material of the config (one of {known})"
    )
    assert not (tmp_path / "o").exists()
