"""Config schema, defaults and the one-line errors of bad configs."""

import copy
import functools
import subprocess
import sys

import pytest
import yaml

from finray.config import (
    ConfigError,
    extra_train_heights,
    face_heights,
    load_config,
    merge_config,
    model_augment_settings,
    model_start,
    read_config_file,
    scenes,
    validate_config,
)

from helpers import ROOT

FULL = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())


def test_full_config_scenes():
    cfg = validate_config(FULL)
    sc = scenes(cfg)
    splits = {s.split for s in sc}
    assert splits == {"train", "shape", "material"}
    # 3 circles + 12 squares in training at the paper's 3 heights and the face's 4; 3 held-out
    # shapes at 3 + 6 heights; the ring x 3 materials at the paper's 3
    assert extra_train_heights(cfg) == []
    assert sum(s.split == "train" for s in sc) == 15 * 7
    assert sum(s.split == "shape" for s in sc) == 3 * 9
    assert sum(s.split == "material" for s in sc) == 3 * 3
    assert sorted({s.material for s in sc if s.split == "material"}) == [
        "neoprene",
        "ninjaflex",
        "steel",
    ]
    assert len({s.id for s in sc}) == len(sc)
    # no held-out shape is tested at a face height that a training scene uses
    train_h = {s.height_mm for s in sc if s.split == "train"}
    assert not set(cfg["face_heights_mm"]["shape"]) & train_h


def test_face_heights_leave_out_objects_below_the_base():
    """face_heights_mm: each split's objects also at those heights, except where an object
    would reach below the clamped base; a height above the finger is refused."""
    cfg = validate_config(
        {**copy.deepcopy(FULL), "face_heights_mm": {"train": [5, 12], "shape": [45]}}
    )
    train5 = {s.object for s in scenes(cfg) if s.split == "train" and s.height_mm == 5}
    # circle_d5 and the 5 mm squares at 0 deg reach 2.5 mm below their centre; the
    # 10 mm circle 5 mm: it just touches y = 0 (allowed, as for heights_mm)
    assert {"circle_d5", "square_s5_a0", "circle_d10", "square_s10_a0"} <= train5
    assert not {"circle_d20", "square_s15_a0", "square_s10_a15"} & train5
    assert face_heights(cfg, "circle_d20") == [12.0]
    assert face_heights(cfg, "ellipse_16x9") == [45.0] and face_heights(cfg, "ring_d15") == []
    assert {s.height_mm for s in scenes(cfg) if s.split == "material"} == {20.0, 30.0, 40.0}
    with pytest.raises(ConfigError, match="face_heights_mm.shape"):
        validate_config({**copy.deepcopy(FULL), "face_heights_mm": {"shape": [85]}})


def test_extra_train_heights_add_training_scenes_only():
    """extra_train_heights_mm: the training objects at the extra heights (of every model,
    or of one), the test objects at heights_mm only."""
    cfg = validate_config(
        {
            **copy.deepcopy(FULL),
            "face_heights_mm": {},
            "extra_train_heights_mm": {"camera": [17, 20], "plain": [45]},
        }
    )
    assert extra_train_heights(cfg) == [17.0, 45.0]  # 20 is a paper height already
    assert (
        extra_train_heights(cfg, "camera") == [17.0] and extra_train_heights(cfg, "occlusion") == []
    )
    sc = scenes(cfg)
    assert sum(s.split == "train" for s in sc) == 15 * 5
    assert {s.height_mm for s in sc if s.split != "train"} == {20.0, 30.0, 40.0}
    assert len({s.id for s in sc}) == len(sc)


def test_a_model_entry_splits_into_augmentation_and_its_start():
    """train.models.<model>: start_from, epochs and ema_decay say how it trains; the rest
    are the augmentation's settings."""
    cfg = validate_config(
        bad(
            lambda c: c["train"]["models"]["occlusion"].update(
                start_from="plain", epochs=4, ema_decay=0.99
            )
        )
    )
    entry = cfg["train"]["models"]["occlusion"]
    assert model_augment_settings(entry) == {
        k: v for k, v in entry.items() if k not in ("start_from", "epochs", "ema_decay")
    }
    assert not {"start_from", "ema_decay"} & set(model_augment_settings(entry))
    assert model_start(cfg, "occlusion") == {"from": "plain", "epochs": 4}
    assert model_start(cfg, "plain") == {"from": None, "epochs": None}
    assert model_start(cfg, "camera") == {"from": None, "epochs": 14}  # its own count


def test_smoke_config_is_valid_and_small():
    cfg = load_config(ROOT / "config" / "smoke.yaml")
    assert len(scenes(cfg)) < len(scenes(validate_config(FULL)))
    assert {s.split for s in scenes(cfg)} == {"train", "shape", "material"}


DIVERSE = read_config_file(ROOT / "config" / "diverse.yaml")  # config.yaml + generated
SLICE = yaml.safe_load((ROOT / "config" / "diverse_slice.yaml").read_text())


@functools.cache
def _diverse_validated() -> dict:
    """validate_config(DIVERSE), once (its 300 generated objects: about 19 CPU-s)."""
    return validate_config(copy.deepcopy(DIVERSE))


@pytest.mark.slow
def test_diverse_config_is_the_paper_config_plus_generated_objects():
    """config/diverse.yaml: config/config.yaml unchanged (it extends it) plus 300
    generated training objects, at the training's heights; the held-out test scenes are
    the paper's."""
    raw = yaml.safe_load((ROOT / "config" / "diverse.yaml").read_text())
    assert sorted(raw) == ["extends", "generated"] and raw["extends"] == "config.yaml"
    assert {k: v for k, v in DIVERSE.items() if k != "generated"} == FULL
    paper, cfg = validate_config(FULL), copy.deepcopy(_diverse_validated())
    blobs = [n for n in cfg["objects"] if n not in paper["objects"]]
    assert blobs == [f"blob_s{s:03d}" for s in range(300)]
    assert {n: cfg["objects"][n] for n in paper["objects"]} == paper["objects"]
    sc = scenes(cfg)
    # each blob at the paper's heights and at the face heights where it clears the base
    assert len(sc) == len(scenes(paper)) + sum(3 + len(face_heights(cfg, b)) for b in blobs)
    assert {s.height_mm for s in sc if s.object in blobs} == {
        12.0,
        20.0,
        30.0,
        40.0,
        50.0,
        60.0,
        70.0,
    }
    assert {(s.split, s.material) for s in sc if s.object in blobs} == {("train", "steel")}
    held_out = sorted(s.id for s in sc if s.split != "train")
    assert held_out == sorted(s.id for s in scenes(paper) if s.split != "train")
    assert validate_config(cfg) == cfg  # a validated config validates again unchanged


@pytest.mark.slow
def test_diverse_slice_is_the_first_blobs_of_the_full_set():
    """Merged after diverse.yaml (as Snakemake merges --configfile a b), the slice keeps
    60 blobs with the same specs: their geometry and FEA jobs are the full set's."""
    assert SLICE == {"generated": {"count": 60}}
    merged = copy.deepcopy(DIVERSE)
    merged["generated"].update(SLICE["generated"])
    full, part = _diverse_validated(), validate_config(merged)
    blobs = [n for n in part["objects"] if n.startswith("blob_")]
    assert blobs == [f"blob_s{s:03d}" for s in range(60)]
    assert all(part["objects"][n] == full["objects"][n] for n in blobs)


@pytest.mark.parametrize(
    "key, value",
    [
        ("seed", 7),
        ("size_mm", [5.0, 20.0]),
        ("harmonics", 3),
        ("amplitude", 0.2),
        ("split", "shape"),
        ("materials", ["steel", "ninjaflex"]),
    ],
)
def test_generated_keys_are_in_every_blob_spec(key, value):
    """Each generated.* value reaches each blob's objects entry (what its jobs declare)."""
    base = {"objects": {"c": {"type": "circle", "diameter_mm": 10}}, "generated": {"count": 3}}
    a = validate_config(base)
    b = validate_config({**base, "generated": {"count": 3, key: value}})
    blobs = [n for n in a["objects"] if n != "c"]
    if key == "seed":
        assert [n for n in b["objects"] if n != "c"] == ["blob_s007", "blob_s008", "blob_s009"]
    else:
        assert all(a["objects"][n] != b["objects"][n] for n in blobs)


def test_defaults_filled():
    cfg = validate_config({"objects": {"c": {"type": "circle", "diameter_mm": 10}}})
    assert cfg["finger"]["ribs"]["angle_step_deg"] == 3.0
    assert cfg["mesh"]["order"] == 2
    assert cfg["placement"]["gap_mm"] == 0.1
    assert cfg["objects"]["c"]["materials"] == ["steel"]
    assert cfg["heights_mm"] == [20, 30, 40]


def bad(mutate):
    cfg = copy.deepcopy(FULL)
    mutate(cfg)
    return cfg


BAD = {
    "unknown object type": (
        lambda c: c["objects"]["circle_d5"].update(type="hexagon"),
        "objects.circle_d5.type",
    ),
    "negative thickness": (
        lambda c: c["finger"].update(wall_thickness_mm=-1.0),
        "finger.wall_thickness_mm",
    ),
    "rib does not fit": (lambda c: c["finger"]["ribs"].update(count=16), "finger.ribs.spacing_mm"),
    "rib into the base": (
        lambda c: c["finger"]["ribs"].update(first_height_mm=4.0),
        "finger.ribs.first_height_mm",
    ),
    "contact height above the finger": (lambda c: c.update(heights_mm=[20, 95]), "heights_mm"),
    "extra height above the finger": (
        lambda c: c.update(extra_train_heights_mm={"camera": [95]}),
        "extra_train_heights_mm.camera",
    ),
    "extra heights of an unknown model": (
        lambda c: c.update(extra_train_heights_mm={"cam": [17]}),
        "extra_train_heights_mm.cam",
    ),
    "unknown key": (lambda c: c["finger"].update(colour="red"), "finger.colour"),
    "missing size": (
        lambda c: c["objects"]["circle_d5"].pop("diameter_mm"),
        "objects.circle_d5.diameter_mm",
    ),
    "unknown material": (
        lambda c: c["objects"]["circle_d20"].update(materials=["gold"]),
        "objects.circle_d20.materials",
    ),
    "self-intersecting polygon": (
        lambda c: c["objects"].update(
            bow={"type": "polygon", "vertices_mm": [[0, 0], [4, 4], [4, 0], [0, 4]]}
        ),
        "objects.bow.vertices_mm",
    ),
    "rigid finger": (lambda c: c["finger"].update(material="steel"), "finger.material"),
    "crop not 2:1": (
        lambda c: c.setdefault("dataset", {}).update(crop_y_mm=[0.0, 70.0]),
        "dataset.crop_y_mm",
    ),
    "input size not rendered": (
        lambda c: c["train"].update(input_size=[96, 48]),
        "train.input_size",
    ),
    "study size not rendered": (
        lambda c: c.setdefault("benchmarks", {}).update(train_sizes=[[96, 48]]),
        "benchmarks.train_sizes",
    ),
    "latency of an unknown model": (
        lambda c: c.setdefault("benchmarks", {}).update(latency_model="x"),
        "benchmarks.latency_model",
    ),
    "generated sizes reversed": (
        lambda c: c.update(generated={"count": 2, "size_mm": [25.0, 5.0]}),
        "generated.size_mm",
    ),
    "generated name taken": (
        lambda c: (
            c.update(generated={"count": 2}),
            c["objects"].update(blob_s001={"type": "circle", "diameter_mm": 10}),
        )[0],
        "generated.seed",
    ),
    "blob without seed": (
        lambda c: c["objects"].update(b={"type": "blob", "diameter_mm": 10}),
        "objects.b.seed",
    ),
    "blob too rough": (
        lambda c: c["objects"].update(
            b={"type": "blob", "seed": 1, "diameter_mm": 10, "amplitude": 0.9}
        ),
        "objects.b.amplitude",
    ),
    "unknown pitch object": (
        lambda c: c.setdefault("dataset", {}).update(pitch_object="nope"),
        "dataset.pitch_object",
    ),
    "start from an unknown model": (
        lambda c: c["train"]["models"]["occlusion"].update(start_from="nope"),
        "train.models.occlusion.start_from",
    ),
    "a model starts from itself": (
        lambda c: c["train"]["models"]["occlusion"].update(start_from="occlusion"),
        "train.models.occlusion.start_from",
    ),
    "models start from one another": (
        lambda c: (
            c["train"]["models"]["occlusion"].update(start_from="plain"),
            c["train"]["models"]["plain"].update(start_from="occlusion"),
        )[0],
        "train.models.plain.start_from",
    ),
    "no epochs": (
        lambda c: c["train"]["models"]["occlusion"].update(epochs=0),
        "train.models.occlusion.epochs",
    ),
    "diversity compared on a fine-tuned model": (
        lambda c: (
            c.update(generated={"count": 2, "compare_model": "occlusion"}),
            c["train"]["models"]["occlusion"].update(start_from="plain"),
        )[0],
        "generated.compare_model",
    ),
    "spread model not trained": (
        lambda c: c.setdefault("evaluate", {}).update(spread={"models": ["camera", "nope"]}),
        "evaluate.spread.models",
    ),
    "spread without sim-to-real's model": (
        lambda c: c.setdefault("evaluate", {}).update(spread={"models": ["plain"]}),
        "evaluate.spread.models",
    ),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_config_names_the_key(case):
    mutate, key = BAD[case]
    with pytest.raises(ConfigError) as err:
        validate_config(bad(mutate))
    assert err.value.key == key
    assert str(err.value).startswith(key + ":")
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    "case",
    [
        "unknown object type",
        "negative thickness",
        "rib does not fit",
        "contact height above the finger",
        "self-intersecting polygon",
    ],
)
def test_bad_config_cli_one_line_and_exit_code(case, tmp_path):
    mutate, key = BAD[case]
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(bad(mutate)))
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "finray.cli",
            "geometry",
            "--config",
            str(path),
            "--out",
            str(tmp_path / "out"),
        ],
        capture_output=True,
        text=True,
    )
    assert r.returncode != 0
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and key in lines[0], r.stderr
    assert not (tmp_path / "out").exists()  # stopped before any work


def test_one_schema_the_package_ships_the_workflow_schema():
    """``src/finray/config.schema.yaml`` is a link to ``workflow/schemas/config.schema.yaml``
    (one file to edit) and the package reads the same bytes (package-data)."""
    from importlib import resources

    workflow_schema = ROOT / "workflow" / "schemas" / "config.schema.yaml"
    link = ROOT / "src" / "finray" / "config.schema.yaml"
    assert link.is_symlink() and link.resolve() == workflow_schema.resolve()
    shipped = resources.files("finray").joinpath("config.schema.yaml").read_bytes()
    assert shipped == workflow_schema.read_bytes()


def test_extends_merges_mappings_and_replaces_the_rest(tmp_path):
    """A config that extends another: mappings merged key by key, lists and values
    replaced, the path relative to the file; a file that extends itself is one line."""
    (tmp_path / "base.yaml").write_text("a: {x: 1, y: [1, 2]}\nb: 3\n")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "over.yaml").write_text("extends: ../base.yaml\na: {y: [9]}\nc: 4\n")
    assert read_config_file(tmp_path / "sub" / "over.yaml") == {
        "a": {"x": 1, "y": [9]},
        "b": 3,
        "c": 4,
    }
    assert merge_config({"a": {"x": 1}}, {"a": 2}) == {"a": 2}
    (tmp_path / "loop.yaml").write_text("extends: loop.yaml\nb: 1\n")
    with pytest.raises(ConfigError) as err:
        read_config_file(tmp_path / "loop.yaml")
    assert str(err.value).startswith("extends:") and "extends itself" in str(err.value)


def test_spread_config_is_the_paper_config_with_the_spread_in_the_manuscript():
    """config/spread.yaml: config/config.yaml with evaluate.spread only changed."""
    cfg = load_config(ROOT / "config" / "spread.yaml")
    paper = validate_config(FULL)
    assert cfg["evaluate"]["spread"] == {
        "seeds": [0, 1, 2],
        "types": ["auto", "fp32"],
        "models": [],
        "manuscript": True,
    }
    cfg["evaluate"]["spread"] = paper["evaluate"]["spread"]
    assert cfg == paper


def test_fast_config_is_the_paper_config_at_the_budget_point_w8x2():
    """config/fast.yaml: config/config.yaml with the train keys of the training-budget
    point w8x2 (whose measured errors docs/studies/training-budget.md gives) and nothing else changed."""
    cfg = load_config(ROOT / "config" / "fast.yaml")
    paper = validate_config(FULL)
    point = paper["benchmarks"]["training_budget"]["points"]["w8x2"]
    assert point == {"base_channels": 8, "lr": 0.0008}
    assert {k: cfg["train"][k] for k in point} == point
    cfg["train"].update({k: paper["train"][k] for k in point})
    assert cfg == paper


def test_pitch_model_config_is_the_paper_config_with_the_pitch_model():
    """config/pitch_model.yaml: config/config.yaml with the pitch-augmented model added to
    its models (the default run trains it no more) and nothing else changed; the smoke
    config trains all four, so that each model's path runs in CI."""
    cfg = load_config(ROOT / "config" / "pitch_model.yaml")
    paper = validate_config(FULL)
    assert "pitch" not in paper["train"]["models"]
    assert set(cfg["train"]["models"]) == set(paper["train"]["models"]) | {"pitch"}
    assert cfg["train"]["models"]["pitch"] == {"pitch_p": 0.5, "pitch_max_deg": 30.0}
    del cfg["train"]["models"]["pitch"]
    assert cfg == paper
    smoke = load_config(ROOT / "config" / "smoke.yaml")
    # the same augmentation; the smoke config's occlusion model is fine-tuned from plain,
    # so that CI runs that path too
    assert {m: model_augment_settings(e) for m, e in smoke["train"]["models"].items()} == {
        **{m: model_augment_settings(e) for m, e in paper["train"]["models"].items()},
        "pitch": {"pitch_p": 0.5, "pitch_max_deg": 30.0},
    }
    assert model_start(smoke, "occlusion") == {"from": "plain", "epochs": 1}


def test_nested_config_values_are_typed_as_yaml_types_them():
    """Snakemake reads ``--config "train={lr: 0.0001}"`` with YAML's base loader (every
    scalar a string); the workflow types them again."""
    from finray.config import typed_overrides

    raw = {
        "train": {"lr": "0.0001", "schedule": "constant", "bn_frames": "0", "eps": "1e-4"},
        "fea": {"push_mm": "5", "flags": ["true", "x"]},
        "seed": 3,
    }
    assert typed_overrides(raw) == {
        "train": {"lr": 0.0001, "schedule": "constant", "bn_frames": 0, "eps": 1e-4},
        "fea": {"push_mm": 5, "flags": [True, "x"]},
        "seed": 3,
    }


def test_a_config_of_changes_only_is_read_on_top_of_the_defaults(tmp_path):
    from finray.config import read_config_file

    path = tmp_path / "mine.yaml"
    path.write_text("train: {epochs: 3}\n")
    cfg = read_config_file(path)
    assert cfg["train"]["epochs"] == 3 and cfg["objects"] == FULL["objects"]
    assert validate_config(cfg)["train"]["epochs"] == 3


@pytest.mark.slow
@pytest.mark.parametrize(
    "how",
    [
        ["--configfile", "{mine}"],
        [
            "--config",
            "train={lr: 0.0001, schedule: constant, bn_frames: 0, keep: val_loss}",
            "fea={push_mm: 5}",
        ],
    ],
)
def test_the_documented_overrides_plan(tmp_path, how):
    """docs/studies/seeds.md's nested --config line and a file of changes only, with
    Snakemake (a dry run)."""
    mine = tmp_path / "mine.yaml"
    mine.write_text("train: {epochs: 3}\n")
    argv = [a.replace("{mine}", str(mine)) for a in how]
    r = subprocess.run(
        [sys.executable, "-m", "snakemake", "-n", "--cores", "2", "--quiet", "rules", *argv],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0 and "config error" not in r.stderr, r.stderr[-2000:]


def test_finray_reads_a_config_of_changes_only_with_the_defaults(tmp_path, monkeypatch):
    """``finray ... --config mine.yaml`` where mine.yaml holds ``train: {epochs: 3}`` only:
    the command sees the default config with that change (the finger and objects of
    config/config.yaml), not an empty one."""
    from finray.cli import _raw_config

    mine = tmp_path / "mine.yaml"
    mine.write_text("train: {epochs: 3}\n")
    monkeypatch.chdir(tmp_path)  # away from the source tree's own config
    raw = _raw_config(mine)
    assert raw["train"]["epochs"] == 3
    assert raw["objects"] == FULL["objects"] and raw["finger"] == FULL["finger"]
