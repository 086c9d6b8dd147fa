"""No stage imports a later one: data flows geometry -> fea -> render -> dataset ->
train -> evaluate -> paper, and an import against that flow is a defect.

The ranks are defined here once. A module may import finray modules of its own rank
or lower. The top-level modules that are not stages get the rank of what they import:

- ``errors``, ``logs``, ``precision``, ``paper_reference``, ``media``, ``annotate``,
  ``lazy``, ``schema``, ``numba_cache``, ``outputs``, ``_start``, ``scheduler_timers``,
  ``viscoelastic``, ``plotting``: import nothing of finray but
  ``errors``; shared
  helpers (rank 0; ``errors`` holds the package's exceptions, ``media`` reads camera
  frames for predict and recording, ``annotate`` draws predict's output over them,
  ``lazy`` loads a package's names on first use, ``schema`` reads the config schema's
  defaults for every stage's settings, ``numba_cache`` points Numba's cache away from
  the source tree; ``outputs``, where every command's outputs go; ``scheduler_timers``
  ends Snakemake's rate-limit timers with the run; ``viscoelastic``, a print's time
  dependence, which the emulated print obeys and a calibration fits; ``plotting``, the
  figures' matplotlib backend and saving).
- ``config``: validates every section, so it imports geometry (shapes), render and
  dataset (their parameters): above dataset, below train. No stage below it may
  import it (the FEA studies do, from ``benchmarks``).
- ``model``, ``train``: the train stage; ``predictor`` runs a trained model on camera
  frames (dataset's image ops) and is what evaluate scores; ``predict`` runs it over
  files and live sources (render's image I/O).
- ``sim2real``: a package ranked by module. ``sim2real.adapt`` fits a rig's force heads
  on a trained model, ``sim2real.calibration`` the sensor model on them (from ingested
  takes: recording's level), ``sim2real.rig_prior`` the gain's prior from FEA variants:
  at train's rank, so that ``predict`` may apply a calibration; ``sim2real.experiment``
  and ``sim2real.rigs`` score and draw: evaluate's rank.
- ``emulator``: the emulated rig: FEA results through a camera into takes (render's level
  and up: rank 35). ``recording``: a real rig's takes -> shards, the dataset stage's
  counterpart; it must never import ``emulator`` (ingest must not see the emulator's truth).
- ``benchmarks``: the studies, a consumer of every stage like evaluate; no stage and
  not evaluate imports it. ``cli``: the entry point, on top.
"""

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src" / "finray"  # tests/workflow/ -> the repo

RANK = {
    "__init__": 0,
    "errors": 0,
    "logs": 0,
    "precision": 0,
    "paper_reference": 0,
    "media": 0,
    "annotate": 0,
    "lazy": 0,
    "schema": 0,
    "numba_cache": 0,
    "outputs": 0,
    "scheduler_timers": 0,
    "viscoelastic": 0,
    "plotting": 0,
    "geometry": 10,
    "fea": 20,
    "render": 30,
    "emulator": 35,
    "dataset": 40,
    "recording": 40,
    "config": 45,
    "model": 50,
    "train": 50,
    "predictor": 50,
    "predict": 50,
    "sim2real": 50,
    "sim2real.adapt": 50,
    "sim2real.calibration": 50,
    "sim2real.rig_prior": 50,
    "sim2real.experiment": 60,
    "sim2real.rigs": 60,
    "validity": 50,
    "evaluate": 60,
    "benchmarks": 70,
    "cli": 80,
    # the `finray` command's entry point (`python -m finray`, the console script) and
    # its first code (imports nothing of finray; finray/__init__ runs it first)
    "_start": 0,
    "__main__": 80,
}


def _unit(parts: list[str]) -> str:
    """The rank key of module ``finray.<parts>``: its sub-package or top-level module
    (``__init__`` for names of the package itself, e.g. ``__version__``); a module of a
    package ranked by module (``sim2real.adapt``) where ``RANK`` names it."""
    if len(parts) > 1 and ".".join(parts[:2]) in RANK:
        return ".".join(parts[:2])
    if parts and ((SRC / parts[0]).is_dir() or (SRC / f"{parts[0]}.py").is_file()):
        return parts[0]
    return "__init__"


def finray_imports(source: str, module: str) -> list[tuple[int, str]]:
    """(line, dotted target) of every import of a finray module in ``source``, the text
    of module ``module`` (e.g. ``finray.render.scene``), relative imports resolved."""
    package = module.split(".")[:-1]  # a module's package (for __init__: the package)
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                names = [node.module] if node.module else [a.name for a in node.names]
                out += [(node.lineno, ".".join(base + [n])) for n in names]
            elif node.module and node.module.split(".")[0] == "finray":
                out.append((node.lineno, node.module))
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.split(".")[0] == "finray"]
    return out


def upward_imports(source: str, module: str) -> list[str]:
    """The imports of ``source`` (module ``module``) that reach a higher rank."""
    own = _unit(module.split(".")[1:])
    if own not in RANK:
        return [f"{module}: the unit '{own}' has no rank"]
    bad = []
    for line, target in finray_imports(source, module):
        unit = _unit(target.split(".")[1:])
        if unit not in RANK:
            bad.append(f"{module}:{line}: imports {target}, whose unit '{unit}' has no rank")
        elif RANK[unit] > RANK[own]:
            bad.append(
                f"{module}:{line}: {own} (rank {RANK[own]}) imports {target} "
                f"({unit}, rank {RANK[unit]})"
            )
    return bad


def _modules():
    for f in sorted(SRC.rglob("*.py")):
        parts = f.relative_to(SRC.parent).with_suffix("").parts
        yield f, ".".join(parts)


def test_every_unit_has_a_rank():
    units = {_unit(list(m.split(".")[1:])) for _, m in _modules()}
    assert units - set(RANK) == set(), "rank the new units in tests/workflow/test_layering.py"


def test_no_stage_imports_a_later_one():
    bad = [b for f, m in _modules() for b in upward_imports(f.read_text(), m)]
    assert bad == []


def test_ingest_never_sees_the_emulator():
    """A real rig's takes go through the same code: recording imports nothing of the emulator
    (whose takes carry the truth beside them), nor does predict(or) or train."""
    bad = [
        f"{m}:{line}: {target}"
        for f, m in _modules()
        if _unit(m.split(".")[1:]) in ("recording", "predictor", "predict", "train", "model")
        for line, target in finray_imports(f.read_text(), m)
        if _unit(target.split(".")[1:]) == "emulator"
    ]
    assert bad == []


@pytest.mark.parametrize(
    "module, source, n_bad",
    [
        ("finray.render.bench", "from ..dataset.shards import FramePreparer\n", 1),
        (
            "finray.fea.studies",
            "from ..config import validate_config\nfrom .simulate import x\n",
            1,
        ),
        ("finray.geometry.mesh", "import finray.train\nfrom finray.geometry import finger\n", 1),
        ("finray.dataset.__init__", "from .shards import load_shard\n", 0),
        ("finray.train", "from .dataset import load_frames\nfrom .evaluate import metrics\n", 1),
        ("finray.cli", "from . import __version__\nfrom .benchmarks import speed\n", 0),
        ("finray.evaluate.speed", "from ..benchmarks.pareto import pareto_front\n", 1),
    ],
)
def test_the_check_finds_upward_imports(module, source, n_bad):
    assert len(upward_imports(source, module)) == n_bad


def test_planning_the_dag_imports_no_torch():
    """What the workflow imports to plan the DAG (the rule files' top-level finray
    imports) loads no torch: a dry run stays quick and needs no network stack."""
    import re
    import subprocess
    import sys

    rules = sorted((SRC.parents[1] / "workflow" / "rules").glob("*.smk"))
    modules = sorted(
        {m for r in rules for m in re.findall(r"^from (finray[\w.]*) import", r.read_text(), re.M)}
    )
    assert "finray.train.config" in modules
    code = (
        "import sys\n" + "".join(f"import {m}\n" for m in modules) + "print('torch' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", modules


def test_reading_shards_and_training_load_no_renderer_or_mesher():
    """Training and a reader of shards (the train stage, load_frames, the pitch
    augmentation) load neither the meshing library (triangle), nor VTK, nor the
    rasterisers: a training machine needs only the train stage's packages."""
    import subprocess
    import sys

    code = (
        "import sys\nimport finray.train.stage, finray.train.augment, finray.dataset.pitch\n"
        "from finray.dataset import load_frames\n"
        "print(sorted(m for m in ('triangle', 'vtk', 'pyvista', 'finray.render.raster',\n"
        "                         'finray.render.perspective', 'finray.geometry.mesh')\n"
        "             if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def _module_file(target: str) -> str | None:
    """The module (``finray.a.b``) that an import target names: itself, or the module
    holding the name it imports; None for a package (its ``__init__`` re-exports)."""
    parts = target.split(".")
    for n in (len(parts), len(parts) - 1):
        path = SRC.parent.joinpath(*parts[:n])
        if path.with_suffix(".py").is_file():
            return ".".join(parts[:n])
        if path.is_dir():
            return None
    return None


def test_no_import_circle():
    """No module reaches itself through the imports of others, late imports included
    (a package's ``__init__``, which re-exports its modules, is left out)."""
    from graphlib import CycleError, TopologicalSorter

    graph = {}
    for f, m in _modules():
        if f.name == "__init__.py":
            continue
        targets = {_module_file(t) for _, t in finray_imports(f.read_text(), m)}
        graph[m] = targets - {None, m}
    try:
        TopologicalSorter(graph).prepare()
    except CycleError as exc:
        pytest.fail(f"import circle: {' -> '.join(exc.args[1])}")


def test_architecture_names_every_stage_of_the_layering_map():
    text = (SRC.parents[1] / "docs" / "architecture.md").read_text()
    missing = [m for m in RANK if f"`{m}`" not in text]
    assert not missing, missing


def unit_cycles(modules) -> list[tuple[str, str]]:
    """Pairs of units of ``modules`` ((module name, source) pairs) that import each other."""
    edges = {
        (own, unit)
        for m, source in modules
        for own in [_unit(m.split(".")[1:])]
        for _, target in finray_imports(source, m)
        for unit in [_unit(target.split(".")[1:])]
        if unit != own and unit != "__init__"
    }
    return sorted((a, b) for a, b in edges if (b, a) in edges and a < b)


def test_no_two_units_import_each_other():
    """Within a rank too, imports run one way (sim2real's scoring uses evaluate's metrics;
    evaluate imports nothing of sim2real)."""
    assert unit_cycles((m, f.read_text()) for f, m in _modules()) == []


def test_the_check_finds_a_cycle():
    modules = [
        ("finray.evaluate.figures", "from ..sim2real.rigs import rigs_table\n"),
        ("finray.sim2real.rigs", "from ..evaluate.figures import _plt\n"),
    ]
    assert unit_cycles(modules) == [("evaluate", "sim2real.rigs")]
