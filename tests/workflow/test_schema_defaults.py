"""The config schema is the one home of every default: a dataclass field that stands for a
config key takes its default with ``schema_default``, never as a literal of its own."""

import ast
from dataclasses import fields
from pathlib import Path

import pytest

import finray
from finray.schema import frozen, load_schema, schema_default, schema_node

SRC = Path(finray.__file__).parent

#: Fields whose literal default equals a same-named key's default but which are not that
#: key, with the reason.
NOT_CONFIG_KEYS = {
    ("IngestParams", "seed"): "ingest's own draws (the QA frames), no config key",
    ("IngestParams", "min_object_frac"): "the colour segmentation of a camera frame "
    "(recording), not the dataset's grey segmentation",
    ("FingerFinder", "min_object_frac"): "the colour segmentation of a camera frame",
}

#: Fields named apart from their config key: (class, field) -> key path.
RENAMED = {
    ("ContactParams", "dhat"): "fea.dhat_mm",
    ("ContactParams", "kappa"): "fea.barrier_stiffness_MPa",
    ("ContactParams", "mu"): "fea.friction",
    ("ContactParams", "eps_v"): "fea.static_slip_mm",
    ("NewtonOptions", "tol_residual"): "fea.residual_tol",
    ("NetConfig", "height"): "train.input_size",
    ("NetConfig", "width"): "train.input_size",
}


def _schema_defaults() -> dict[str, list[tuple[str, object]]]:
    """Key name -> [(path, frozen default)] of every key with a default."""
    out: dict[str, list] = {}

    def walk(node, path):
        for k, sub in node.get("properties", {}).items():
            p = f"{path}.{k}" if path else k
            if "default" in sub:
                out.setdefault(k, []).append((p, frozen(sub["default"])))
            walk(sub, p)

    walk(load_schema(), "")
    return out


def _dataclass_fields():
    """(file, class name, field name, default expression) of every dataclass field with a
    default in the package's source."""
    for path in sorted(SRC.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for cls in ast.walk(tree):
            if not isinstance(cls, ast.ClassDef) or not any(
                "dataclass" in ast.unparse(d) for d in cls.decorator_list
            ):
                continue
            for st in cls.body:
                if (
                    isinstance(st, ast.AnnAssign)
                    and st.value is not None
                    and isinstance(st.target, ast.Name)
                ):
                    yield path.relative_to(SRC.parent), cls.name, st.target.id, st.value


def _same(a, b) -> bool:
    return a == b and (type(a) is type(b) or isinstance(a, tuple))


def test_no_default_is_written_twice():
    """A literal default equal to the schema's default of a key of the same name is a
    second copy of it (the two drift apart: RenderParams.files_per_scene said None while
    the schema said 5)."""
    keys = _schema_defaults()
    twice = []
    for path, cls, name, value in _dataclass_fields():
        try:
            lit = frozen(ast.literal_eval(value))
        except ValueError:
            continue
        if lit is None:  # "not given": too common to be a copy of the schema's null
            continue
        hits = [p for p, d in keys.get(name, []) if _same(d, lit)]
        if hits and (cls, name) not in NOT_CONFIG_KEYS:
            twice.append(f"{path}: {cls}.{name} = {lit!r} is the schema's {hits[0]}")
    assert not twice, "defaults written twice (use finray.schema.schema_default):\n" + "\n".join(
        twice
    )


def test_schema_defaults_name_their_own_key():
    """Each ``schema_default("<path>")`` of a dataclass field names a key with a default,
    the field's own (same name, or a declared rename)."""
    wrong, n = [], 0
    for path, cls, name, value in _dataclass_fields():
        if not (isinstance(value, ast.Call) and ast.unparse(value.func) == "schema_default"):
            continue
        n += 1
        key = ast.literal_eval(value.args[0])
        expected = RENAMED.get((cls, name))
        if not (key == expected if expected else key.rsplit(".", 1)[-1] == name):
            wrong.append(f"{path}: {cls}.{name} takes the default of {key}")
        elif "default" not in schema_node(key):
            wrong.append(f"{path}: {cls}.{name}: {key} has no default in the schema")
    assert n > 100, n  # the config's dataclasses are scanned
    assert not wrong, "\n".join(wrong)


#: Function parameters whose literal default equals a same-named key's schema default but
#: which are not that key: (function, parameter) -> the reason. Every ``seed`` is left out
#: too: nine sections have a key ``seed`` (each 0), and a function's seed is its own
#: random stream's, 0 by convention, not one of those keys.
NOT_CONFIG_PARAMS = {
    ("evaluate", "order"): "fea: the derivative order (energy, gradient, Hessian), "
    "not the mesh's element order",
    ("evaluate_numpy", "order"): "fea: the derivative order, not the element order",
    ("fea_forces", "split"): "the split read, not generated.split (the generated objects')",
    ("training_data", "split"): "the split read, not generated.split",
    ("annotated_figure", "distance_mm"): "the render viewpoint picked for the figure, "
    "not the lab camera's distance",
    ("segment_finger", "min_object_frac"): "the colour segmentation of a camera frame "
    "(recording), not the dataset's grey segmentation",
    ("segment_finger", "max_hole_frac"): "the colour segmentation of a camera frame",
    ("colour_finder", "min_object_frac"): "the colour segmentation of a camera frame",
    ("learn_finder", "min_object_frac"): "the colour segmentation of a camera frame",
    ("predict_files", "device"): "finray predict's --device, not train.device",
    ("check_setup", "device"): "finray predict's --device, not train.device",
    ("__init__", "device"): "the Predictor's device (finray predict --device), not train.device",
    ("predictive", "chunk"): "frames per chunk of the predictive draw, "
    "not the sampler's steps per chunk",
}

#: Repeated defaults still to be fixed: (file, function, parameter).
PENDING: set[tuple[str, str, str]] = set()


def _function_defaults():
    """(file, function name, parameter name, default expression) of every parameter with a
    default of every function in the package's source."""
    for path in sorted(SRC.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for fn in ast.walk(tree):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            a = fn.args
            pos = a.posonlyargs + a.args
            pairs = list(zip(pos[len(pos) - len(a.defaults) :], a.defaults))
            pairs += [(x, d) for x, d in zip(a.kwonlyargs, a.kw_defaults) if d is not None]
            for arg, d in pairs:
                yield path.relative_to(SRC.parent), fn.name, arg.arg, d


def test_no_argument_default_is_written_twice():
    """A function's literal default equal to the schema's default of a key of the same
    name is a second copy of it: take it with ``schema_default`` (evaluated at import)."""
    keys = _schema_defaults()
    twice, n = [], 0
    for path, fn, name, value in _function_defaults():
        n += 1
        try:
            lit = frozen(ast.literal_eval(value))
        except ValueError:
            continue
        if lit is None or name == "seed":
            continue
        hits = [p for p, d in keys.get(name, []) if _same(d, lit)]
        if not hits or (fn, name) in NOT_CONFIG_PARAMS:
            continue
        if (path.as_posix(), fn, name) not in PENDING:
            twice.append(f"{path}: {fn}({name}={lit!r}) is the schema's {hits[0]}")
    assert n > 500, n  # the package's functions are scanned
    assert not twice, "defaults written twice (use finray.schema.schema_default):\n" + "\n".join(
        twice
    )


def test_argument_schema_defaults_name_their_own_key():
    """Each ``schema_default("<path>")`` of a function parameter names a key with a
    default, of the parameter's own name."""
    wrong, n = [], 0
    for path, fn, name, value in _function_defaults():
        if not (isinstance(value, ast.Call) and ast.unparse(value.func) == "schema_default"):
            continue
        n += 1
        key = ast.literal_eval(value.args[0])
        if key.rsplit(".", 1)[-1] != name:
            wrong.append(f"{path}: {fn}({name}) takes the default of {key}")
        elif "default" not in schema_node(key):
            wrong.append(f"{path}: {fn}({name}): {key} has no default in the schema")
    assert n >= 40, n
    assert not wrong, "\n".join(wrong)


def _section_defaults(path: str) -> dict:
    return {k: v["default"] for k, v in schema_node(path)["properties"].items() if "default" in v}


@pytest.mark.parametrize(
    "cls_path, section",
    [
        ("finray.render.params.RenderParams", "render"),
        ("finray.dataset.params.DatasetParams", "dataset"),
        ("finray.render.camera_views.CameraViews", "render.camera_views"),
        ("finray.emulator.motion.GripperMotion", "lab.motion"),
        ("finray.emulator.sensor.ForceSensor", "lab.sensor"),
        ("finray.geometry.finger.FingerParams", "finger"),
    ],
)
def test_a_class_built_from_the_schema_defaults_is_its_default(cls_path, section):
    """``from_config`` of the section the schema fills in on an empty config gives the
    class's defaults: the same values and the same types (tuples, floats)."""
    import importlib

    module, name = cls_path.rsplit(".", 1)
    cls = getattr(importlib.import_module(module), name)
    built = cls.from_config(
        _section_defaults(section)
        | ({"ribs": _section_defaults("finger.ribs")} if section == "finger" else {})
    )
    assert built == cls()
    for f in fields(cls):
        assert type(getattr(built, f.name)) is type(getattr(cls(), f.name)), f.name


def test_the_train_section_defaults_are_train_configs():
    from finray.train import TrainConfig

    cfg = TrainConfig()
    for k, v in _section_defaults("train").items():
        if hasattr(cfg, k):
            assert getattr(cfg, k) == v, k


def test_schema_default_names_a_missing_key():
    with pytest.raises(KeyError, match="render.no_such_key: not a key"):
        schema_default("render.no_such_key")
    with pytest.raises(KeyError, match="train.models.plain"):
        schema_default("train.models.plain")
    assert schema_default("render.window_x_mm") == (-5.0, 35.0)
    assert schema_default("dataset.sizes") == ((128, 64), (64, 32))


def test_the_input_window_of_the_schema_defaults_is_its_default():
    """The window built from the schema's finger and dataset sections is InputWindow(),
    and so is the one DatasetParams() gives for the schema's base width."""
    from finray.dataset import DatasetParams
    from finray.dataset.window import InputWindow

    built = InputWindow.from_sections(_section_defaults("finger"), _section_defaults("dataset"))
    assert built == InputWindow() == DatasetParams().window(schema_default("finger.base_width_mm"))
    assert InputWindow.from_json(built.to_json()) == (built, [])
