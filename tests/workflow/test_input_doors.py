"""Every input checked at the door (issue 55): a bad config, number, option, path or
saved file stops a ``finray`` command with one line on stderr (``finray <command>:
<message>``), exit code 2, no traceback and nothing written."""

import json
from pathlib import Path

import pytest
import yaml

from finray.cli import main
from finray.config import ConfigError, check_config, read_config_file, validate_config
from finray.sim2real.calibration import PARAMS

CONFIGS = Path(__file__).resolve().parents[2] / "config"


def refused(argv, out, capsys) -> str:
    """``finray <argv>``: exit code 2, nothing on stdout, one line on stderr naming the
    command, and ``out`` not created; the line."""
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse's own errors (one line: cli._Parser)
        rc = exc.code
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert rc == 2, (rc, cap.err)
    assert cap.out == "" and "Traceback" not in cap.err
    assert len(lines) == 1 and lines[0].startswith(f"finray {argv[0]}: "), cap.err
    assert not out.exists(), f"{out} was written"
    return lines[0]


def config_file(tmp_path, text: str):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    return str(path)


def command(name: str, tmp_path, cfg: str) -> list[str]:
    """A ``finray <name>`` that reads ``--config cfg`` (its other input need not exist:
    the config is checked first)."""
    out = str(tmp_path / "out")
    return {
        "ingest": ["ingest", str(tmp_path / "take"), "--config", cfg, "--out", out],
        "calibrate": ["calibrate", str(tmp_path / "take"), "--model", str(tmp_path / "m.pt"),
                      "--config", cfg, "--out", str(tmp_path / "out" / "cal.json")],
        "geometry": ["geometry", "--config", cfg, "--out", out],
        "simulate": ["simulate", "--object", "circle", "--size-mm", "20", "--height-mm", "30",
                     "--config", cfg, "--out", out],
    }[name]  # fmt: skip


CONFIG_CASES = {
    "misspelt section": (
        "ingest",
        "datasett: {}\n",
        "config error: datasett: not a config key; did you mean 'dataset'?",
    ),
    "misspelt nested key": (
        "calibrate",
        "evaluate:\n  sim2real:\n    levle: 0.9\n",
        "config error: evaluate.sim2real.levle: not a config key; did you mean 'level'?",
    ),
    "nan gap": (
        "geometry",
        "placement:\n  gap_mm: .nan\n",
        "config error: placement.gap_mm: must be a finite number, got nan",
    ),
    "nan level": (
        "calibrate",
        "evaluate:\n  sim2real:\n    level: .nan\n",
        "config error: evaluate.sim2real.level: must be a finite number, got nan",
    ),
    "level above 1": (
        "calibrate",
        "evaluate:\n  sim2real:\n    level: 5\n",
        "config error: evaluate.sim2real.level: 5 is greater than or equal to the maximum of 1",
    ),
    "level a word": (
        "calibrate",
        "evaluate:\n  sim2real:\n    level: wide\n",
        "config error: evaluate.sim2real.level: 'wide' is not of type 'number'",
    ),
    "size a letter": (
        "ingest",
        "dataset:\n  sizes: [[b, 64]]\n",
        "config error: dataset.sizes.0.0: 'b' is not of type 'integer'",
    ),
    "crop a word": (
        "ingest",
        "dataset:\n  crop_x_mm: [high, 35.0]\n",
        "config error: dataset.crop_x_mm.0: 'high' is not of type 'number'",
    ),
    "nan crop": (
        "ingest",
        "dataset:\n  crop_y_mm: [.nan, 80.0]\n",
        "config error: dataset.crop_y_mm.0: must be a finite number, got nan",
    ),
    "crop not 2:1": (
        "ingest",
        "dataset:\n  crop_y_mm: [0.0, 70.0]\n",
        "config error: dataset.crop_y_mm: the crop (40 x 70 mm) must be twice as tall",
    ),
    "nan mesh size": (
        "geometry",
        "mesh:\n  size_mm: .nan\n",
        "config error: mesh.size_mm: must be a finite number, got nan",
    ),
    "infinite fea push": (
        "simulate",
        "fea:\n  push_mm: .inf\n",
        "config error: fea.push_mm: must be a finite number, got inf",
    ),
    "model name a path": (
        "geometry",
        "train:\n  models:\n    ../../../../tmp/x: {occlusion_p: 0.5}\n",
        "config error: train.models: '../../../../tmp/x' is not a name",
    ),
}


@pytest.mark.parametrize("case", list(CONFIG_CASES))
def test_every_command_checks_its_config_against_the_schema(case, tmp_path, capsys):
    name, text, message = CONFIG_CASES[case]
    line = refused(command(name, tmp_path, config_file(tmp_path, text)), tmp_path / "out", capsys)
    assert line.startswith(f"finray {name}: {message}"), line


def test_snakemakes_validation_is_the_same(tmp_path):
    """validate_config (the workflow's) says what the subcommands say, on a whole config."""
    full = read_config_file(CONFIGS / "config.yaml")
    for mutate, message in [
        (
            lambda c: c["evaluate"].setdefault("sim2real", {}).update(levle=0.9),
            "evaluate.sim2real.levle: not a config key; did you mean 'level'?",
        ),
        (
            lambda c: c.update(datasett={}),
            "datasett: not a config key; did you mean 'dataset'?",
        ),
        (
            lambda c: c.setdefault("placement", {}).update(gap_mm=float("nan")),
            "placement.gap_mm: must be a finite number, got nan",
        ),
        (
            lambda c: c["train"]["models"].update({"../../../../tmp/x": {}}),
            "train.models: '../../../../tmp/x' is not a name",
        ),
        (
            lambda c: c.update(extra_train_heights_mm={"../x": [17.0]}),
            "extra_train_heights_mm: '../x' is not a name",
        ),
    ]:
        cfg = json.loads(json.dumps(full))
        mutate(cfg)
        with pytest.raises(ConfigError) as err:
            validate_config(cfg)
        assert str(err.value).startswith(message), str(err.value)


@pytest.mark.parametrize("path", ["config.yaml", "smoke.yaml", "diverse.yaml", "diverse_slice.yaml",
                                  "fast.yaml", "pitch_model.yaml", "spread.yaml"])  # fmt: skip
def test_every_shipped_config_passes_the_schema(path):
    raw = read_config_file(CONFIGS / path)
    check_config(raw, whole="objects" in raw)  # diverse_slice: an overlay


@pytest.mark.parametrize(
    "argv, message",
    [
        (
            ["geometry", "--object", "circle", "--size-mm", "20", "--angle-deg", "nan"],
            "--angle-deg must be a finite number of degrees, got nan",
        ),
        (
            ["simulate", "--object", "circle", "--size-mm", "20", "--height-mm", "30",
             "--angle-deg", "nan"],
            "--angle-deg must be a finite number of degrees, got nan",
        ),
        (
            ["geometry", "--object", "circle", "--size-mm", "20", "--angle-deg", "400"],
            "--angle-deg must be between -360 and 360 degrees, got 400",
        ),
        (
            ["geometry", "--object", "circle", "--size-mm", "inf"],
            "--size-mm must be a finite number of mm, got inf",
        ),
        (
            ["geometry", "--object", "circle", "--size-mm", "20", "--height-mm", "nan"],
            "--height-mm must be a finite number of mm, got nan",
        ),
        (
            ["simulate", "--object", "circle", "--size-mm", "20", "--height-mm", "30",
             "--mesh-size-mm", "nan"],
            "--mesh-size-mm must be a finite number of mm, got nan",
        ),
        (
            ["geometry", "--object", "square", "--size-mm", "20", "--fillet-mm", "-1"],
            "--fillet-mm must be >= 0 mm, got -1",
        ),
        (
            ["predict", "--model", "m.ts", "src", "--threads", "99999999999"],
            "--threads must be between 1 and ",
        ),
        (["predict", "--model", "m.ts", "src", "--check", "0"], "--check must be >= 1 frames, got 0"),
        (
            ["geometry", "--object", "circle", "--size-mm", "abc"],
            "argument --size-mm: invalid float value: 'abc'",
        ),
    ],
)  # fmt: skip
def test_every_number_on_the_command_line_is_finite_and_in_range(argv, message, tmp_path, capsys):
    out = tmp_path / "out"
    line = refused([*argv, "--out", str(out)], out, capsys)
    assert line.startswith(f"finray {argv[0]}: {message}"), line


@pytest.mark.parametrize(
    "argv, message",
    [
        (["geometry", "--object", "circle", "--object", "square", "--size-mm", "20"],
         "--object takes one value, got circle and square"),
        (["geometry", "--object", "circle", "--size-mm", "20", "--size-mm", "3"],
         "--size-mm takes one value, got 20.0 and 3.0"),
        (["geometry", "--object", "circle", "--size-mm", "20", "--out", "elsewhere", "--out", "out"],
         "--out takes one value, got elsewhere and out"),
        (["predict", "--model", "m.ts", "src", "--threads", "2", "--threads", "1"],
         "--threads takes one value, got 2 and 1"),
        (["ingest", "take", "--config", "a.yaml", "--config", "b.yaml"],
         "--config takes one value, got a.yaml and b.yaml"),
        (["calibrate", "take", "--model", "a.pt", "--model", "b.pt", "--out", "x.json"],
         "--model takes one value, got a.pt and b.pt"),
    ],
)  # fmt: skip
def test_an_option_of_one_value_refuses_a_second(argv, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    argv = argv if "--out" in argv else [*argv, "--out", str(out)]
    line = refused(argv, out, capsys)
    assert line.startswith(f"finray {argv[0]}: {message}"), line
    assert not (tmp_path / "elsewhere").exists()


def _take(folder, **meta):
    """A take folder with only its take.json (read first, before the frames)."""
    folder.mkdir(parents=True)
    meta = {"object": "cylinder", "contact_height_mm": 20.0, "push_axis": "fz", **meta}
    (folder / "take.json").write_text(json.dumps(meta))
    return folder


@pytest.mark.parametrize(
    "meta, message",
    [
        ({"contact_height_mm": float("nan")}, "contact_height_mm: must be a finite number, got nan"),
        ({"camera": {"px_per_mm": float("inf")}}, "camera/px_per_mm: must be a finite number, got inf"),
        ({"video": "../other/take.mp4"}, "video: '../other/take.mp4' is not a file in the take's own"),
        ({"video": "/tmp/take.mp4"}, "video: '/tmp/take.mp4' is not a file in the take's own"),
    ],
)  # fmt: skip
def test_a_take_json_with_a_nan_or_a_video_elsewhere_is_refused(meta, message, tmp_path, capsys):
    take = _take(tmp_path / "t1", **meta)
    out = tmp_path / "out"
    line = refused(["ingest", str(take), "--out", str(out)], out, capsys)
    assert line.startswith(f"finray ingest: {take / 'take.json'}: {message}"), line


@pytest.mark.parametrize("how", ["dotdot", "twice"])
def test_calibrate_refuses_takes_without_a_folder_of_their_own(how, tmp_path, capsys):
    a, b = _take(tmp_path / "a" / "t1"), _take(tmp_path / "b" / "t1")
    takes = [str(a / "..")] if how == "dotdot" else [str(a), str(b)]
    out = tmp_path / "out"
    line = refused(
        ["calibrate", *takes, "--model", str(tmp_path / "m.pt"), "--out", str(out / "cal.json")],
        out,
        capsys,
    )
    if how == "dotdot":
        assert "its path has no folder name of its own" in line, line
    else:
        assert f"takes {a} and {b} have the same folder name 't1'" in line, line
    assert not list(tmp_path.glob("**/*.ingest"))


def _calibration(folder, **over):
    folder.mkdir(parents=True, exist_ok=True)
    cal = {"posterior": {"samples": [[1.0] * 6 + [0.0] * (len(PARAMS) - 6)] * 4}, "level": 0.9,
           "model": "cal.model.ts", **over}  # fmt: skip
    path = folder / "cal.json"
    path.write_text(json.dumps(cal))
    return path


@pytest.mark.parametrize(
    "over, message",
    [
        ({"level": float("nan")}, "level must be a number in (0, 1) (the predictive interval's), got nan"),
        ({"level": 90}, "level must be a number in (0, 1) (the predictive interval's), got 90"),
        ({"model": "../../elsewhere/model.ts"}, "model '../../elsewhere/model.ts' is not a file in"),
        ({"model": "/tmp/model.ts"}, "model '/tmp/model.ts' is not a file in"),
        ({"posterior": {"samples": [[float("nan")] * len(PARAMS)]}}, "posterior samples that are not finite"),
    ],
)  # fmt: skip
def test_predict_refuses_a_calibration_with_a_bad_level_or_a_model_elsewhere(
    over, message, tmp_path, capsys
):
    cal = _calibration(tmp_path / "rig", **over)
    out = tmp_path / "out"
    line = refused(["predict", "--calibration", str(cal), "frames", "--out", str(out)], out, capsys)
    assert line.startswith(f"finray predict: {cal}: {message}"), line


def test_a_config_file_given_to_a_command_is_not_changed(tmp_path):
    """The check reads the config as written (its defaults are filled in a copy)."""
    raw = {"dataset": {"crop_x_mm": [-5.0, 35.0]}}
    check_config(raw, whole=False)
    assert raw == {"dataset": {"crop_x_mm": [-5.0, 35.0]}}
    assert yaml.safe_dump(raw)


def test_every_mapping_of_the_schema_is_closed_or_its_keys_are_names():
    """Each mapping of the config schema refuses unknown keys (additionalProperties:
    false), or, where its keys are free (objects, materials, train.models, ...), takes
    names only: a key that becomes a folder or a file name cannot be a path."""
    from finray.schema import load_schema

    def walk(node, where):
        if isinstance(node, list):
            for i, n in enumerate(node):
                yield from walk(n, f"{where}[{i}]")
            return
        if not isinstance(node, dict):
            return
        kind = node.get("type")
        if kind == "object" or (isinstance(kind, list) and "object" in kind):
            yield where, node
        for k, v in node.items():
            if k not in ("default", "if"):
                yield from walk(v, f"{where}/{k}")

    open_maps = []
    for where, node in walk(load_schema(), ""):
        extra = node.get("additionalProperties")
        if extra is None or (extra is not False and "propertyNames" not in node):
            open_maps.append(where)
    assert not open_maps, open_maps


@pytest.mark.parametrize("key", ["frame_step_mm", "max_step_mm"])
def test_an_fea_step_too_small_to_finish_is_refused(key):
    """A step of 1e-6 mm passed and started a push of millions of solves (the fuzz test)."""
    with pytest.raises(
        ConfigError, match=rf"^fea\.{key}: 1e-06 is less than the minimum of 0\.01$"
    ):
        check_config({"fea": {key: 1e-6}}, whole=False)
    assert check_config({"fea": {key: 0.01}}, whole=False)["fea"][key] == 0.01
