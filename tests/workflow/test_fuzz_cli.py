"""Every door fuzzed (issue 55): Hypothesis draws ``finray`` command lines from each
subcommand's real parser (its options, with valid values, edge numbers, empty strings,
missing paths, files of the wrong kind, repeated and unknown flags) and configs mutated
from config/smoke.yaml at keys of the config schema. One invariant for every run: exit 0
with complete outputs, or exit 2 with exactly one line on stderr (``finray <command>:
...``), or exit 1 (failed part way: a solve, skipped frames) ending with that line;
never a traceback; nothing half-written: ``--out`` absent or as it was, or complete,
nothing else written, the inputs untouched (a folder of them given as ``--out
--overwrite`` may be replaced, whole, where it holds none of the run's inputs).

The CLI runs in-process (:func:`finray.cli.main`) on tiny inputs (a coarse mesh and a
0.5 mm push, a 64 x 32 network, three frames, a 2 s take), seeded
(``derandomize``) and bounded, so that the file takes about a minute on two cores.
``calibrate`` is never given a take it could ingest (a valid run takes minutes): its
doors are fuzzed, not its fit."""

from __future__ import annotations

import argparse
import copy
import itertools
import json
import os
import re
import shutil
import warnings
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from finray.cli import build_parser, main
from finray.config import check_config, validate_config
from finray.errors import BadInput
from finray.schema import load_schema

from helpers import PREPROCESS
from recording_synth import write_take, write_video

pytestmark = pytest.mark.slow  # ~1 min: not in `pytest -m "not slow"`

ROOT = Path(__file__).resolve().parents[2]
SMOKE = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())


def fuzz_settings(n: int):
    """Seeded (the same examples every run), bounded, no example database on disk."""
    return settings(
        derandomize=True,
        database=None,
        max_examples=n * int(os.environ.get("FINRAY_FUZZ_SCALE", "1")),  # more: a deeper search
        deadline=None,
        suppress_health_check=[
            HealthCheck.function_scoped_fixture,  # capfd, monkeypatch: read per example
            HealthCheck.too_slow,
            HealthCheck.data_too_large,
        ],
    )


# -- the inputs ----------------------------------------------------------------------


def _small_configs() -> dict:
    """Configs whose valid runs take a fraction of a second: one object at one height, a
    3 mm mesh with coarse fillets, a 0.5 mm push in one frame."""
    geo = copy.deepcopy(SMOKE)
    geo["objects"] = {"circle_d10": {"type": "circle", "diameter_mm": 10, "split": "train"}}
    geo["heights_mm"] = [30]
    geo["face_heights_mm"] = {}
    geo["mesh"] = {"size_mm": 3.0, "arc_chord_mm": 1.0}
    sim = copy.deepcopy(geo)
    sim["fea"] = {"push_mm": 0.5, "frame_step_mm": 0.5, "max_step_mm": 0.5, "write_vtu": False}
    cheap_heads = {"heads": {"members": 2, "epochs": 0, "steps": 20}, "sampler": {"max_steps": 500}}
    return {
        "geo_yaml": geo,
        "sim_yaml": sim,
        "ingest_yaml": {"dataset": {"sizes": [[64, 32]]}},
        "calibrate_yaml": {"dataset": {"sizes": [[64, 32]]}, "evaluate": {"sim2real": cheap_heads}},
    }


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """Every input a drawn token (``@name``) can stand for, valid and not, built once;
    none of them may change (:func:`_state` compared after each example)."""
    import torch

    from finray.model import FinRayNet, NetConfig
    from finray.sim2real.calibration import PARAMS
    from finray.train import History, export_torchscript, save_checkpoint

    d = tmp_path_factory.mktemp("fuzz_inputs")
    w: dict[str, Path] = {}
    for name, cfg in _small_configs().items():
        w[name] = d / f"{name.removesuffix('_yaml')}.yaml"
        w[name].write_text(yaml.safe_dump(cfg))
    # a tiny network: checkpoint, TorchScript and its settings (with their hashes)
    torch.manual_seed(0)
    net = FinRayNet(NetConfig(in_channels=1, base_channels=4, height=64, width=32)).eval()
    (d / "model").mkdir()
    save_checkpoint(net, History(), d / "model" / "model.pt")
    export_torchscript(net, d / "model" / "model.ts", PREPROCESS)
    w["model_pt"], w["model_ts"] = d / "model" / "model.pt", d / "model" / "model.ts"
    # a take (frames/ + frames.csv, forces.csv, take.json), 160 x 120, two pushes in 2 s
    truth = write_take(
        d / "take", size=(160, 120), duration_s=2.0, fps=15.0, starts=(0.3, 1.1), ramp=0.3,
        hold=0.2, kind="frames",
    )  # fmt: skip
    w["take"] = d / "take"
    (d / "frames").mkdir()
    for f in sorted((d / "take" / "frames").glob("*.png"))[10:13]:
        shutil.copy(f, d / "frames" / f.name)
    w["frames"], w["image"] = d / "frames", d / "frames" / "f00010.png"
    w["clip"] = d / "clip.mp4"
    write_video(w["clip"], truth["frames"][10:14], 10.0)
    # a calibration of the same network (its model beside it, as calibrate writes it)
    (d / "rig").mkdir()
    shutil.copy(w["model_ts"], d / "rig" / "cal.model.ts")
    shutil.copy(d / "model" / "model.ts.json", d / "rig" / "cal.model.ts.json")
    samples = [[1.0, 0.0, -2.0, -1.0, -1.0, 1.5, 0.0, 0.0, 0.0]] * 8  # the print's law: elastic
    assert len(samples[0]) == len(PARAMS)
    cal = {"posterior": {"samples": samples}, "level": 0.9, "model": "cal.model.ts"}
    w["calibration"] = d / "rig" / "cal.json"
    w["calibration"].write_text(json.dumps(cal))
    w["polygon"] = d / "part.json"
    w["polygon"].write_text("[[-4, -4], [5, -3], [1, 6]]")
    # wrong kinds of files
    w["missing"] = d / "no" / "such" / "file.yaml"
    w["empty"] = d / "empty.yaml"
    w["empty"].write_bytes(b"")
    w["folder"] = d / "an_empty_folder"
    w["folder"].mkdir()
    w["text"] = d / "notes.txt"
    w["text"].write_text("not what was asked for\n")
    w["binary"] = d / "noise.bin"
    w["binary"].write_bytes(np.random.default_rng(0).bytes(512))
    w["yaml_list"] = d / "list.yaml"
    w["yaml_list"].write_text("- a\n- b\n")
    w["json_nan"] = d / "nan.json"
    w["json_nan"].write_text("[[NaN, 1], [2, Infinity], [1, 1e999]]")
    np.savez(d / "whole.npz", a=np.arange(1000.0))
    w["truncated_npz"] = d / "truncated.npz"
    w["truncated_npz"].write_bytes((d / "whole.npz").read_bytes()[:300])
    w["truncated_zip"] = d / "truncated.pt"  # torch's zip format, cut short
    w["truncated_zip"].write_bytes(w["model_pt"].read_bytes()[:2000])
    w["bad_take"] = d / "t1"  # take.json only: refused before any frame is read
    w["bad_take"].mkdir()
    (w["bad_take"] / "take.json").write_text(
        json.dumps({"object": "cylinder", "contact_height_mm": 20.0, "push_axis": "fz"})
    )
    w["nan_take"] = d / "t2"
    w["nan_take"].mkdir()
    (w["nan_take"] / "take.json").write_text('{"contact_height_mm": NaN}')
    with zipfile.ZipFile(d / "zipped.npz", "w") as z:
        z.writestr("a.npy", b"not an array")
    w["bad_npz"] = d / "zipped.npz"
    pristine = tmp_path_factory.mktemp("fuzz_pristine") / "inputs"
    shutil.copytree(d, pristine)  # to put back a folder --out --overwrite may replace
    return {"dir": d, "paths": w, "state": _state(d), "pristine": pristine}


def _state(folder: Path) -> dict:
    """Every entry under ``folder``: kind, size and modification time."""
    return {
        p.relative_to(folder).as_posix(): (p.is_dir(), p.lstat().st_size, p.lstat().st_mtime_ns)
        for p in folder.rglob("*")
    }


# -- the command lines ---------------------------------------------------------------

#: what a value may be, for any option: numbers at the edges, words, empty strings
EDGES = ["0", "-1", "-0", "nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "1e-6", "2.5",
         str(10**30), "99999999999", "", " ", "abc", "1,5", "0x10", "--", "-"]  # fmt: skip
#: paths of the wrong kind (tokens: :func:`_resolve`)
BAD_PATHS = ["@missing", "@empty", "@folder", "@text", "@binary", "@yaml_list", "@json_nan",
             "@truncated_npz", "@truncated_zip", "@bad_npz", "@bad_take", "@nan_take"]  # fmt: skip
#: where --out may point (folder outputs; calibrate's --out is a file: _out_path)
OUTS = ["@out:fresh", "@out:abs", "@out:empty_dir", "@out:used", "@out:file", "@out:under_file",
        "@out:dot", "@out:empty", "@out:nested", "@out:input"]  # fmt: skip
UNKNOWN = ["--bogus", "--out-dir", "-x", "--size", "--obj", "--config=", "---out", "--OUT",
           "--no-such-flag=1", "-h1"]  # fmt: skip


#: the changes to a valid command line, the deeper ones (a value set) the most often
OPS = ["set"] * 6 + ["positional"] * 2 + ["drop", "again", "unknown"]


@dataclass
class Spec:
    """A subcommand's valid command line (option, value; value None: a flag) and its
    positionals, the valid values of each option, the options never left out (a valid
    run without them would take minutes: the full config's FEA)."""

    base: list
    positionals: list
    valid: dict
    pinned: set = field(default_factory=set)


SPECS = {
    "geometry": Spec(
        base=[("--config", "@geo_yaml"), ("--object", "circle"), ("--size-mm", "10"),
              ("--height-mm", "30"), ("--mesh-size-mm", "3"), ("--out", "@out:fresh")],
        positionals=[],
        valid={"--config": ["@geo_yaml", "@sim_yaml"], "--object-file": ["@polygon"],
               "--size-mm": ["8", "12.5"], "--minor-mm": ["5"], "--wall-mm": ["1.5"],
               "--angle-deg": ["15", "-360", "360"], "--fillet-mm": ["0", "0.5"],
               "--height-mm": ["20", "40"], "--mesh-size-mm": ["2.5", "5"]},
        pinned={"--config"},
    ),
    "simulate": Spec(
        base=[("--config", "@sim_yaml"), ("--object", "circle"), ("--size-mm", "10"),
              ("--height-mm", "30"), ("--no-vtu", None), ("--out", "@out:fresh")],
        positionals=[],
        valid={"--config": ["@sim_yaml"], "--object-file": ["@polygon"], "--size-mm": ["8"],
               "--minor-mm": ["5"], "--wall-mm": ["1.5"], "--angle-deg": ["15", "-360"],
               "--fillet-mm": ["0", "0.5"], "--height-mm": ["20", "40"],
               "--mesh-size-mm": ["3", "5"], "--material": ["steel", "ninjaflex", "unobtainium"]},
        pinned={"--config", "--mesh-size-mm"},
    ),
    "predict": Spec(
        base=[("--model", "@model_ts"), ("--out", "@out:fresh")],
        positionals=["@frames"],
        valid={"--model": ["@model_ts", "@model_pt"], "--calibration": ["@calibration"],
               "--threads": ["1", "2"], "--finger-colour": ["orange", "blue", "teal",
               '{"space": "hsv", "lo": [0, 0, 0], "hi": [1, 1, 1]}', '{"space": "hsv"}'],
               "--check": ["1", "3"], "source": ["@frames", "@clip", "@image", "@take", "0"]},
    ),
    "ingest": Spec(
        base=[("--config", "@ingest_yaml"), ("--out", "@out:fresh")],
        positionals=["@take"],
        valid={"--config": ["@ingest_yaml"], "take": ["@take", "@bad_take", "@nan_take"]},
        pinned={"--config"},  # the default config's sizes: a slower valid run
    ),
    "calibrate": Spec(
        base=[("--model", "@model_pt"), ("--config", "@calibrate_yaml"), ("--out", "@out:fresh")],
        positionals=["@bad_take"],
        valid={"--model": ["@model_pt", "@model_ts"], "--no-context": ["@model_pt"],
               "--config": ["@calibrate_yaml"], "takes": ["@bad_take", "@nan_take"]},
    ),
}  # fmt: skip


def _actions(command: str) -> dict:
    """The real parser's options of ``command`` (long name -> action), help left out."""
    sub = build_parser()._subparsers._group_actions[0].choices[command]
    return {
        max(a.option_strings, key=len): a
        for a in sub._actions
        if a.option_strings and not isinstance(a, argparse._HelpAction)
    }


def _values(command: str, option: str, action=None):
    """Values for ``option``: its valid ones, its choices, edge numbers and words, paths
    that are not what it takes."""
    spec = SPECS[command]
    if option == "--out":
        return st.sampled_from(OUTS + EDGES[:4])
    pool = list(spec.valid.get(option, []))
    pool += [str(c) for c in (getattr(action, "choices", None) or [])]
    valid = st.sampled_from(pool) if pool else st.nothing()
    return st.one_of(  # a valid value half the time
        valid,
        valid,
        valid,
        st.sampled_from(EDGES),
        st.sampled_from(BAD_PATHS),
        st.text(alphabet="ab/.-_ 0é\t", max_size=6),
    )


@st.composite
def command_lines(draw, command: str) -> list[str]:
    """A ``finray <command>`` line (tokens unresolved): the valid one, changed 0 to 4
    times (an option left out, set, given again; a flag; an unknown flag; a stray or
    missing positional)."""
    spec, actions = SPECS[command], _actions(command)
    pairs, positionals = list(spec.base), list(spec.positionals)
    positional_name = {"predict": "source", "ingest": "take", "calibrate": "takes"}.get(command)
    for _ in range(draw(st.integers(0, 4))):
        op = draw(st.sampled_from(OPS))
        if op == "drop" and pairs:
            k = draw(st.integers(0, len(pairs) - 1))
            if pairs[k][0] not in spec.pinned:
                del pairs[k]
        elif op in ("set", "again"):
            opt = draw(st.sampled_from(sorted(actions)))
            a = actions[opt]
            if a.nargs == 0:  # a flag
                pairs.append((opt, None))
                continue
            value = draw(_values(command, opt, a))
            if a.nargs == "?" and draw(st.booleans()):
                value = None
            if opt in spec.pinned and not (value in spec.valid[opt] or value.startswith("@")):
                continue  # a pinned option keeps a value that is a file, valid or not
            if op == "set":
                pairs = [p for p in pairs if p[0] != opt]
            pairs.append((opt, value))
        elif op == "unknown":
            pairs.append((draw(st.sampled_from(UNKNOWN)), draw(st.sampled_from([None, "1"]))))
        elif positional_name:  # a positional: another, none, or a different one
            how = draw(st.sampled_from(["replace", "add", "none"]))
            value = draw(_values(command, positional_name).filter(lambda v: v != "--"))
            if how == "none":
                positionals = []
            elif how == "add" or not positionals:
                positionals.append(value)
            else:
                positionals[0] = value
    argv = [command]
    at = draw(st.integers(0, len(pairs)))  # where the positionals go
    for k, (opt, value) in enumerate(pairs):
        if k == at:
            argv += positionals
        argv += [opt] if value is None else [opt, value]
    if at == len(pairs):
        argv += positionals
    return argv


# -- one run and its invariant -------------------------------------------------------


def _out_path(kind: str, ws: Path, world: dict, file_out: bool) -> str:
    """``--out`` of ``kind``, made ready in the example's own folder ``ws`` (the
    current folder); calibrate's (``file_out``) is a file."""
    name = "cal.json" if file_out else "out"
    if kind == "fresh":
        return f"rig/{name}" if file_out else name
    if kind == "abs":
        return str(ws / "abs" / name)
    if kind == "empty_dir":
        (ws / "emptydir").mkdir(exist_ok=True)
        return "emptydir"
    if kind == "used":  # an earlier run's outputs
        if file_out:
            (ws / "cal.json").write_text('{"earlier": true}')
            return "cal.json"
        (ws / "used").mkdir(exist_ok=True)
        (ws / "used" / "earlier.txt").write_text("an earlier run\n")
        return "used"
    if kind in ("file", "under_file"):
        (ws / "afile.txt").write_text("a file\n")
        return "afile.txt" if kind == "file" else "afile.txt/sub"
    if kind == "dot":
        return "."
    if kind == "empty":
        return ""
    if kind == "nested":
        return f"a/b/{name}"
    if kind == "input":  # a folder the run reads
        return str(world["paths"]["frames" if not file_out else "take"])
    raise AssertionError(kind)


def _resolve(token: str, ws: Path, world: dict, file_out: bool) -> str:
    if not token.startswith("@"):
        return token
    if token.startswith("@out:"):
        return _out_path(token[5:], ws, world, file_out)
    return str(world["paths"][token[1:]])


def _complete(command: str, argv: list[str], out: Path, code: int) -> str:
    """'' where ``out`` holds ``command``'s complete outputs, else what is missing."""

    def need(*names):
        missing = [n for n in names if not (out / n).is_file() or (out / n).stat().st_size == 0]
        return f"missing {missing} in {out}" if missing else ""

    if command == "geometry":
        objs = list((out / "objects").glob("*.npz"))
        for f in [out / "finger.npz", *objs]:
            with np.load(f) as z:
                assert len(z.files), f
        return need("finger.npz", "finger.json", "finger.vtu") or ("" if objs else "no object")
    if command == "simulate":
        if code == 1:  # a failed solve: its report
            return need("summary.json")
        json.loads((out / "summary.json").read_text())
        return need("forces.csv", "summary.json", "result.npz")
    if command == "predict":
        if "--check" in argv:
            return need("check.png")
        rows = (
            (out / "forces.csv").read_text().splitlines() if (out / "forces.csv").is_file() else []
        )
        return "" if len(rows) >= 2 else f"no rows in {out / 'forces.csv'}"
    if command == "ingest":
        return need("shard.npz", "frames.csv", "sync.json", "ingest.json")
    if command == "calibrate":
        json.loads(out.read_text())
        return "" if out.with_suffix(".model.ts").is_file() else "no adapted model"
    raise AssertionError(command)


#: the options whose value the run reads (finray.cli._staged's inputs)
INPUT_OPTIONS = {"--model", "--calibration", "--config", "--object-file", "--no-context"}


def _inputs(command: str, argv: list[str]) -> list[Path]:
    """What the run reads: the positionals and the input options' values."""
    actions, found, k = _actions(command), [], 1
    while k < len(argv):
        a = argv[k]
        if a in actions:
            if actions[a].nargs == 0:
                k += 1
                continue
            if a in INPUT_OPTIONS and k + 1 < len(argv):
                found.append(argv[k + 1])
            k += 2
            continue
        found.append(a)
        k += 1
    return [Path(p) for p in found if p]


def _check_inputs(command: str, argv: list[str], code: int, world: dict, ws: Path, why: str):
    """The inputs as they were; or one folder among them replaced, as ``--out``: with
    ``--overwrite``, complete, and holding none of the run's inputs (then put back)."""
    d, now = world["dir"], _state(world["dir"])
    if now == world["state"]:
        return
    outs = [argv[k + 1] for k, a in enumerate(argv[:-1]) if a == "--out"]
    assert code == 0 and outs and "--overwrite" in argv, ("an input changed", why)
    target = Path(os.path.normpath(ws / outs[-1]))
    rel = os.path.relpath(target, d)
    assert rel != "." and not rel.startswith(".."), ("an input changed", why)
    changed = {k for k in set(now) | set(world["state"]) if now.get(k) != world["state"].get(k)}
    assert all(k == rel or k.startswith(rel + "/") for k in changed), (changed, why)
    inputs = [(ws / p).resolve() for p in _inputs(command, argv)]
    held = [p for p in inputs if target in (p, *p.parents)]
    assert not held, ("--overwrite replaced a folder that holds an input", held, why)
    missing = _complete(command, argv, target, code)
    assert not missing, (missing, why)
    shutil.rmtree(target)
    shutil.copytree(world["pristine"] / rel, target)
    world["state"] = _state(d)


_COUNT = itertools.count()


def check_run(tokens: list[str], world: dict, root: Path, capfd) -> tuple[int, str]:
    """Run ``finray <tokens>`` in a folder of its own under ``root`` and check the
    invariant; the exit code and stderr."""
    command = tokens[0]
    ws = root / f"{next(_COUNT):05d}"
    ws.mkdir()
    os.chdir(ws)
    file_out = command == "calibrate"
    try:  # an --out drawn twice: made ready once
        argv = [_resolve(t, ws, world, file_out) for t in tokens]
        before = _state(ws)
        return _run_and_check(command, argv, ws, before, world, root, file_out, capfd)
    finally:
        os.chdir(root)
        shutil.rmtree(ws, ignore_errors=True)


def _run_and_check(command, argv, ws, before, world, root, file_out, capfd):
    capfd.readouterr()
    with warnings.catch_warnings(record=True) as warned:
        warnings.simplefilter("always")
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse's errors: one line (cli._Parser)
            code = exc.code
    cap = capfd.readouterr()
    os.chdir(root)
    shown = [
        f"{w.category.__name__}: {w.message}"
        for w in warned
        if not issubclass(w.category, (DeprecationWarning, PendingDeprecationWarning))
    ]
    lines = cap.err.strip().splitlines()
    why = f"finray {' '.join(map(repr, argv[:]))}\nexit {code}\nstderr:\n{cap.err}"
    # pytest --hypothesis-show-statistics: how often each exit code and each last line
    event(f"exit {code}")
    event(re.sub(r"/\S*|\d+", "#", (lines or [""])[-1])[:90])
    assert "Traceback" not in cap.err + cap.out, why
    assert code in (0, 1, 2), why
    if code == 2:
        assert len(lines) == 1 and lines[0].startswith(f"finray {command}: "), why
        assert not shown, (shown, why)
    if code == 1:
        assert lines and lines[-1].startswith(f"finray {command}: "), why
    # --out: absent or as it was, or complete; nothing else written; the inputs as they were
    outs = [argv[k + 1] for k, a in enumerate(argv[:-1]) if a == "--out"]
    out = (ws / outs[-1]) if outs else None
    after = _state(ws)
    if after != before:
        assert code in (0, 1) and out is not None, ("written", sorted(after), why)
        out = Path(os.path.normpath(out))
        missing = _complete(command, argv, out, code)
        assert not missing, (missing, why)
        rel = os.path.relpath(out, ws)
        changed = {
            k for k in set(before) | set(after)
            if before.get(k) != after.get(k) and not (rel == "." or k == rel or k.startswith(rel + "/"))
        }  # fmt: skip
        if file_out:  # calibrate's companions: <stem>.*
            changed = {k for k in changed if not Path(k).name.startswith(out.stem + ".")}
            changed -= {os.path.dirname(rel)}
        changed -= {k for k in changed if (ws / k).is_dir() and rel.startswith(k + "/")}
        assert not changed, (changed, why)
    if code == 0 and after == before:  # its outputs beside the inputs (--out there)
        assert out is not None and ws not in Path(os.path.normpath(out)).parents, why
    assert not [k for k in after if ".part-" in k], why
    _check_inputs(command, argv, code, world, ws, why)
    beside = [p.name for p in root.iterdir() if p != ws]  # e.g. <out>.part-* of --out .
    assert not beside, (beside, why)
    return code, cap.err


@pytest.fixture
def fuzz_root(tmp_path, monkeypatch):
    """The examples' folders' parent (the current folder is restored after)."""
    monkeypatch.chdir(tmp_path)
    root = tmp_path / "runs"
    root.mkdir()
    return root


# -- the subcommands' flags ----------------------------------------------------------


def _fuzz_command(command: str, n: int):
    @fuzz_settings(n)
    @given(tokens=command_lines(command))
    def test(tokens, world, fuzz_root, capfd):
        check_run(tokens, world, fuzz_root, capfd)

    test.__name__ = f"test_fuzz_{command}_command_lines"
    test.__doc__ = f"``finray {command}``: every command line drawn keeps the invariant."
    return test


test_fuzz_geometry_command_lines = _fuzz_command("geometry", 100)
test_fuzz_simulate_command_lines = _fuzz_command("simulate", 60)
test_fuzz_predict_command_lines = _fuzz_command("predict", 120)
test_fuzz_ingest_command_lines = _fuzz_command("ingest", 35)
test_fuzz_calibrate_command_lines = _fuzz_command("calibrate", 60)


# -- the config schema's keys --------------------------------------------------------


def _schema_paths(base: dict) -> dict:
    """Every key of the config schema (path -> its schema); a free mapping's (objects,
    materials, train.models ...) through the names ``base`` gives it; a list's first item."""
    schema = load_schema()
    defs = schema.get("$defs", {})

    def node_of(n):
        return defs[n["$ref"].split("/")[-1]] if isinstance(n, dict) and "$ref" in n else n

    paths = {}

    def walk(node, cfg, prefix):
        node = node_of(node)
        if not isinstance(node, dict):
            return
        for k, sub in node.get("properties", {}).items():
            paths[prefix + (k,)] = node_of(sub)
            walk(sub, cfg.get(k) if isinstance(cfg, dict) else None, prefix + (k,))
        extra = node_of(node.get("additionalProperties"))
        if isinstance(extra, dict) and isinstance(cfg, dict):
            for k, v in cfg.items():
                paths[prefix + (k,)] = extra
                walk(extra, v, prefix + (k,))
        if isinstance(cfg, list) and cfg:
            paths[prefix + (0,)] = node_of(node.get("items", {}))
            walk(node.get("items", {}), cfg[0], prefix + (0,))

    walk(schema, base, ())
    return dict(sorted(paths.items(), key=lambda kv: str(kv[0])))


#: values of the wrong kind, not finite, huge, negative, empty
NASTY = [float("nan"), float("inf"), float("-inf"), "word", "", [], {}, None, True, -1, 0,
         1e308, -1e308, 10**30, -(10**30), [float("nan")], [[]], 0.5, 1, 2.5, 1e-6,
         "../../x", [1, 2, 3]]  # fmt: skip


def _edges(node: dict) -> list:
    """A key's values at the edges of its schema range, inside and just outside, its
    choices and its default."""
    out = [node[k] for k in ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum")
           if isinstance(node.get(k), (int, float))]  # fmt: skip
    if isinstance(node.get("exclusiveMinimum"), (int, float)):
        out.append(node["exclusiveMinimum"] + 1e-6)
    if isinstance(node.get("exclusiveMaximum"), (int, float)):
        out.append(node["exclusiveMaximum"] - 1e-6)
    out += [v - 1 for v in out if isinstance(v, int)] + list(node.get("enum", []))
    return out + ([node["default"]] if "default" in node else [])


_PATHS: dict[int, dict] = {}  # _schema_paths of a base config


@st.composite
def mutated_configs(draw, base: dict = SMOKE, under: tuple = (), skip: tuple = ()) -> dict:
    """``base`` (config/smoke.yaml) with 1 to 3 keys of the schema (those ``under``
    one of the given sections, if any; not those in ``skip``) deleted, misspelt or set
    to a value of the wrong kind, at or beyond the edge of its range, huge, negative or
    empty (the edges half the time)."""
    cfg = copy.deepcopy(base)
    nodes = _PATHS.get(id(base)) or _PATHS.setdefault(id(base), _schema_paths(base))
    keys = [p for p in nodes if (not under or p[0] in under) and ".".join(map(str, p)) not in skip]
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(keys))
        op = draw(st.sampled_from(["delete", "misspell", "set", "set", "set", "set"]))
        edges = _edges(nodes[path])
        value = draw(st.sampled_from(NASTY) | (st.sampled_from(edges) if edges else st.nothing()))
        value = copy.deepcopy(value)
        parent = cfg
        for k in path[:-1]:  # down to the key's parent, made where it is missing
            if isinstance(parent, dict):
                parent = parent.setdefault(k, {})
            elif isinstance(parent, list) and isinstance(k, int) and k < len(parent):
                parent = parent[k]
            else:
                parent = None
                break
        last = path[-1]
        if isinstance(parent, dict) and isinstance(last, str):
            if op == "delete":
                parent.pop(last, None)
            elif op == "misspell" and last in parent:
                parent[last[:-1] + draw(st.sampled_from("xs_")) + last[-1:]] = parent.pop(last)
            else:
                parent[last] = value
        elif isinstance(parent, list) and isinstance(last, int) and last < len(parent):
            if op == "delete":
                del parent[last]
            else:
                parent[last] = value
    return cfg


def _one_line_config_error(cfg: dict, fn) -> None:
    """``fn(cfg)`` returns, or raises a BadInput (ConfigError) of one line."""
    try:
        fn(copy.deepcopy(cfg))
    except BadInput as exc:
        msg = str(exc)
        assert msg and "\n" not in msg, msg
        assert "Traceback" not in msg


@fuzz_settings(200)
@given(cfg=mutated_configs())
def test_fuzz_validate_config_raises_only_config_errors(cfg):
    """The workflow's validation and the subcommands' schema check: a one-line
    ConfigError (BadInput) or a config, never another exception."""
    _one_line_config_error(cfg, lambda c: check_config(c, whole=False))
    _one_line_config_error(cfg, validate_config)


def _config_file(cfg: dict, folder: Path) -> Path:
    path = folder / "fuzzed.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


@fuzz_settings(60)
@given(cfg=mutated_configs(), command=st.sampled_from(["geometry", "ingest", "calibrate"]))
def test_fuzz_configs_given_to_the_commands(cfg, command, world, fuzz_root, tmp_path, capfd):
    """A mutated config given with --config: the invariant (geometry runs on it, ingest
    on a take, calibrate's doors only)."""
    path = str(_config_file(cfg, tmp_path))
    tokens = {
        "geometry": ["geometry", "--config", path, "--object", "circle", "--size-mm", "10",
                     "--height-mm", "30", "--mesh-size-mm", "3", "--out", "@out:fresh"],
        "ingest": ["ingest", "@take", "--config", path, "--out", "@out:fresh"],
        "calibrate": ["calibrate", "@bad_take", "--model", "@model_pt", "--config", path,
                      "--out", "@out:fresh"],
    }[command]  # fmt: skip
    check_run(tokens, world, fuzz_root, capfd)


SIM = _small_configs()["sim_yaml"]


@fuzz_settings(40)
@given(
    cfg=mutated_configs(
        SIM,
        under=("fea", "finger", "materials", "placement", "mesh"),
        # the size of the work, as --mesh-size-mm: a 50 mm push takes 9 s, and the
        # schema's smallest steps (0.01 mm) 50 solves for this push
        skip=("fea.push_mm", "fea.frame_step_mm", "fea.max_step_mm"),
    ),
    obj=st.sampled_from([["circle", "--size-mm", "10"], ["ring", "--size-mm", "15",
                         "--material", "ninjaflex"]]),
)  # fmt: skip
def test_fuzz_configs_given_to_simulate(cfg, obj, world, fuzz_root, tmp_path, capfd):
    """The FEA's, the finger's and the materials' keys mutated, a 0.5 mm push on a 3 mm
    mesh: the invariant (a solve that fails part way: exit 1 and its report)."""
    path = str(_config_file(cfg, tmp_path))
    tokens = ["simulate", "--config", path, "--object", *obj, "--height-mm", "30",
              "--mesh-size-mm", "3", "--out", "@out:fresh"]  # fmt: skip
    check_run(tokens, world, fuzz_root, capfd)
