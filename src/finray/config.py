"""Configuration: load, fill defaults, validate (schema + geometry), list scenes.

The schema is ``workflow/schemas/config.schema.yaml`` (shipped inside the package
as ``finray/config.schema.yaml``). A bad config raises :class:`ConfigError`
whose message is one line naming the key and the reason.
"""

from __future__ import annotations

import copy
import difflib
import functools
import json
from dataclasses import dataclass
from pathlib import Path

import jsonschema
import yaml

from .geometry.blobs import blob_name, generated_objects
from .geometry.finger import FingerParams, GeometryError, check_ribs, finger_polygon
from .geometry.objects import object_shape, place_object
from .errors import ConfigError
from .schema import load_schema, non_finite


def _extend_with_default(validator_class):
    """Validator that writes each property's ``default`` into the instance."""
    validate_properties = validator_class.VALIDATORS["properties"]

    def set_defaults(validator, properties, instance, schema):
        if isinstance(instance, dict):
            for name, sub in properties.items():
                if "default" in sub and name not in instance:
                    instance[name] = copy.deepcopy(sub["default"])
        yield from validate_properties(validator, properties, instance, schema)

    return jsonschema.validators.extend(validator_class, {"properties": set_defaults})


_Validator = _extend_with_default(jsonschema.Draft202012Validator)


def _key(path) -> str:
    return ".".join(str(p) for p in path) or "<config>"


def _schema_error_message(err: jsonschema.ValidationError) -> ConfigError:
    path = list(err.absolute_path)
    if err.validator == "additionalProperties" and isinstance(err.instance, dict):
        allowed = set(err.schema.get("properties", {}))
        extra = sorted(set(err.instance) - allowed)
        key = _key(path + extra[:1])
        near = difflib.get_close_matches(str(extra[0]), sorted(allowed), n=1) if extra else []
        if near:
            return ConfigError(key, f"not a config key; did you mean '{near[0]}'?")
        return ConfigError(key, f"not a config key (allowed here: {', '.join(sorted(allowed))})")
    if "propertyNames" in err.relative_schema_path:  # a map's key: a name, often a path
        return ConfigError(
            _key(path),
            f"{err.instance!r} is not a name (letters, digits, '_' and '-'"
            + (f"; {err.message}" if err.validator != "pattern" else "")
            + ")",
        )
    if err.validator == "required":
        missing = err.message.split("'")[1] if "'" in err.message else err.message
        return ConfigError(_key(path + [missing]), "is required here")
    if err.validator == "enum":
        return ConfigError(_key(path), f"{err.instance!r} is not one of {err.validator_value}")
    return ConfigError(_key(path), err.message)


def check_config(config: dict, whole: bool = True) -> dict:
    """``config`` checked against the JSON schema (types, units' ranges, unknown keys,
    with the nearest known key named), every number finite: a copy with the defaults
    filled in, or a one-line :class:`ConfigError`. ``whole=False``: a part of a config,
    as a subcommand reads (``finray ingest --config``), where no key is required."""
    cfg = copy.deepcopy(config) if config is not None else {}
    found = non_finite(cfg)
    if found is not None:
        raise ConfigError(_key(found[0]), f"must be a finite number, got {found[1]}")
    schema = load_schema()
    if not whole:
        schema.pop("required", None)
    validator = _Validator(schema)
    errors = sorted(validator.iter_errors(cfg), key=lambda e: (len(e.absolute_path), e.path))
    if errors:
        best = jsonschema.exceptions.best_match(errors)
        raise _schema_error_message(best)
    return cfg


def validate_config(config: dict, base_dir: str | Path = ".") -> dict:
    """Return a validated copy of ``config`` with defaults filled in.

    Checks, in order: the JSON schema and finite numbers (:func:`check_config`), the
    references between sections, the finger geometry (ribs fit) and that every
    object (the generated ones added, see ``generated``) can be placed at every
    contact height. Relative polygon-file paths are resolved against ``base_dir``.
    """
    cfg = check_config(config)
    mats = cfg["materials"]
    if cfg["finger"]["material"] not in mats:
        raise ConfigError(
            "finger.material", f"'{cfg['finger']['material']}' is not a key of materials"
        )
    if mats[cfg["finger"]["material"]]["rigid"]:
        raise ConfigError("finger.material", "the finger cannot be rigid")
    finger = FingerParams.from_config(cfg["finger"])
    if finger.wall_thickness_mm * 2 >= finger.base_width_mm:
        raise ConfigError(
            "finger.wall_thickness_mm", "the walls are thicker than the finger is wide"
        )
    if finger.base_thickness_mm >= finger.height_mm / 2:
        raise ConfigError("finger.base_thickness_mm", "the base plate fills half the finger")
    try:
        check_ribs(finger)
        finger_polygon(finger, cfg["mesh"]["arc_chord_mm"])
    except GeometryError as exc:
        raise ConfigError(exc.key, str(exc).split(": ", 1)[1]) from None
    _add_generated(cfg)
    _check_stage_sections(cfg)
    for h in cfg["heights_mm"]:
        if h >= finger.height_mm:
            raise ConfigError(
                "heights_mm",
                (f"contact height {h} mm is at or above the finger (height {finger.height_mm} mm)"),
            )
    for model, hs in cfg.get("extra_train_heights_mm", {}).items():
        if model not in cfg["train"]["models"]:
            raise ConfigError(f"extra_train_heights_mm.{model}", "is not a model of train.models")
        for h in hs:
            if h >= finger.height_mm:
                raise ConfigError(
                    f"extra_train_heights_mm.{model}",
                    (
                        f"contact height {h} mm is at or above the finger (height {finger.height_mm} mm)"
                    ),
                )
    for split, hs in cfg.get("face_heights_mm", {}).items():
        for h in hs:
            if h >= finger.height_mm:
                raise ConfigError(
                    f"face_heights_mm.{split}",
                    (
                        f"contact height {h} mm is at or above the finger (height {finger.height_mm} mm)"
                    ),
                )
    for name, spec in cfg["objects"].items():
        for m in spec["materials"]:
            if m not in mats:
                raise ConfigError(f"objects.{name}.materials", f"'{m}' is not a key of materials")
        if spec["type"] == "polygon_file":
            p = Path(spec["path"])
            spec["path"] = str(p if p.is_absolute() else Path(base_dir) / p)
        try:
            shape = object_shape(spec, cfg["mesh"]["size_mm"], f"objects.{name}")
            for h in object_heights(cfg, name):
                place_object(shape, finger, h, cfg["placement"]["gap_mm"], f"objects.{name}")
        except GeometryError as exc:
            raise ConfigError(exc.key, str(exc).split(": ", 1)[1]) from None
    _check_lab(cfg, finger)
    _check_start_from(cfg)
    _check_diversity(cfg)
    _check_spread(cfg)
    return cfg


def _add_generated(cfg: dict) -> None:
    """Add the ``generated`` section's objects to ``objects`` (after the explicit ones).
    A validated config validates again unchanged: an existing entry must be the same."""
    try:
        gen = generated_objects(cfg["generated"])
    except GeometryError as exc:
        raise ConfigError(exc.key, str(exc).split(": ", 1)[1]) from None
    for name, spec in gen.items():
        if cfg["objects"].setdefault(name, spec) != spec:
            raise ConfigError(
                "generated.seed",
                (
                    f"generated object '{name}' is also a key of objects (rename it or move the seeds)"
                ),
            )


#: Suffix of the model trained on the paper's objects only (``generated.compare_model``).
PAPER_OBJECTS_SUFFIX = "_paper_objects"


def generated_training_objects(cfg: dict) -> list[str]:
    """Names of the generated objects in the training split (a validated config), sorted."""
    gen = cfg["generated"]
    if gen["split"] != "train" or not gen["count"]:
        return []
    return sorted(blob_name(s) for s in range(gen["seed"], gen["seed"] + gen["count"]))


def diversity_models(cfg: dict) -> tuple[str, str] | None:
    """``(paper-objects model, model)`` of the diversity comparison: ``generated.compare_model``
    trained on the paper's objects only beside the same model trained with the generated
    ones; None where no generated object trains or ``compare_model`` is null."""
    base = cfg["generated"]["compare_model"]
    if base is None or not generated_training_objects(cfg):
        return None
    return f"{base}{PAPER_OBJECTS_SUFFIX}", base


def _check_diversity(cfg: dict) -> None:
    """The compared model is one of train.models, and its paper-objects twin is not."""
    pair = diversity_models(cfg)
    if pair is None:
        return
    models = cfg["train"]["models"]
    if pair[1] not in models:
        raise ConfigError(
            "generated.compare_model",
            (
                f"'{pair[1]}' is not a key of train.models ({', '.join(sorted(models))}); null: no comparison"
            ),
        )
    if pair[0] in models:
        raise ConfigError(
            "generated.compare_model",
            (f"train.models already has '{pair[0]}', the name of its paper-objects model"),
        )
    if models[pair[1]].get("start_from") is not None:
        raise ConfigError(
            "generated.compare_model",
            (
                f"'{pair[1]}' starts from another model's weights (train.models.{pair[1]}.start_from), "
                "which saw the generated objects: compare a model trained from scratch"
            ),
        )


#: keys of a train.models entry that set how it trains, not how its frames are augmented
#: (the others are finray.train.AugmentConfig's)
MODEL_TRAINING_KEYS = ("start_from", "epochs", "ema_decay")


def model_augment_settings(entry: dict) -> dict:
    """A train.models entry's augmentation settings (finray.train.AugmentConfig's keys)."""
    return {k: v for k, v in entry.items() if k not in MODEL_TRAINING_KEYS}


def model_start(cfg: dict, name: str) -> dict:
    """How train.models' ``name`` trains: ``from``, the model whose weights it starts
    from (None: from scratch), and ``epochs``, its own count (None: train.epochs)."""
    entry = cfg["train"]["models"][name]
    return {"from": entry.get("start_from"), "epochs": entry.get("epochs")}


def _check_start_from(cfg: dict) -> None:
    """Each start_from names another model of train.models, and no chain of them loops."""
    models = cfg["train"]["models"]
    for name in sorted(models):
        chain = [name]
        while (src := models[chain[-1]].get("start_from")) is not None:
            key = f"train.models.{chain[-1]}.start_from"
            if src not in models:
                raise ConfigError(
                    key, f"'{src}' is not a key of train.models ({', '.join(sorted(models))})"
                )
            if src in chain:
                raise ConfigError(
                    key, f"the models start from one another: {' -> '.join(chain + [src])}"
                )
            chain.append(src)


def _check_spread(cfg: dict) -> None:
    """The studies' models are models of train.models, and hold sim-to-real's model."""
    models = cfg["train"]["models"]
    chosen = cfg["evaluate"]["spread"]["models"]
    unknown = [m for m in chosen if m not in models]
    if unknown:
        raise ConfigError(
            "evaluate.spread.models",
            (f"{', '.join(map(repr, unknown))} not in train.models ({', '.join(sorted(models))})"),
        )
    start = sim2real_model_name(cfg)
    if chosen and start not in chosen:
        raise ConfigError(
            "evaluate.spread.models", (f"must hold '{start}', the model sim-to-real starts from")
        )


def _check_lab(cfg: dict, finger: FingerParams) -> None:
    """The emulated rig's objects fit the finger at its heights, its motion fits its take."""
    from .emulator.as_built import as_built_finger
    from .emulator.motion import GripperMotion

    lab = cfg["lab"]
    try:
        GripperMotion.from_config(lab["motion"])
    except ValueError as exc:
        raise ConfigError("lab.motion", str(exc).split(": ", 1)[-1]) from None
    if lab["motion"]["push_mm"] + lab["motion"]["gap_mm"] > finger.base_width_mm:
        raise ConfigError("lab.motion.push_mm", "the push goes through the finger")
    built = FingerParams.from_config(as_built_finger(cfg["finger"], lab["as_built"]))
    try:
        check_ribs(built)
        for name, spec in lab["objects"].items():
            shape = object_shape(spec, cfg["mesh"]["size_mm"], f"lab.objects.{name}")
            for h in lab["heights_mm"]:
                place_object(shape, built, h, lab["motion"]["gap_mm"], f"lab.objects.{name}")
    except GeometryError as exc:
        raise ConfigError(exc.key, str(exc).split(": ", 1)[1]) from None


def section_params(section: str, build, value):
    """``build(value)``, the parameters of config section ``section``; its cross-key
    checks' ``ValueError`` or ``TypeError`` as a one-line :class:`ConfigError` naming
    the key."""
    import re

    try:
        return build(value)
    except (ValueError, TypeError) as exc:
        if isinstance(exc, ConfigError):
            raise
        m = re.match(rf"({section}\.[A-Za-z_]+)[: ]+(.*)", str(exc))
        key, msg = (m.group(1), m.group(2)) if m else (section, str(exc))
        raise ConfigError(key, msg) from None


def _check_stage_sections(cfg: dict) -> None:
    """Cross-key checks of the render, dataset and train sections."""
    from .dataset.params import DatasetParams
    from .dataset.splits import pitch_object
    from .render.params import RenderParams

    for section, build in (
        ("render", RenderParams.from_config),
        ("dataset", DatasetParams.from_config),
    ):
        section_params(section, build, cfg[section])
    if cfg["dataset"].get("pitch_object"):  # a named one must exist (else: the first shape)
        try:
            pitch_object(cfg)
        except ValueError as exc:
            raise ConfigError("dataset.pitch_object", str(exc).split(": ", 1)[-1]) from None
    sizes = [list(s) for s in cfg["dataset"]["sizes"]]
    if list(cfg["train"]["input_size"]) not in sizes:
        raise ConfigError(
            "train.input_size",
            (f"{cfg['train']['input_size']} is not one of dataset.sizes {sizes}"),
        )
    if cfg["train"]["input_size"][0] % 16 or cfg["train"]["input_size"][1] % 16:
        raise ConfigError("train.input_size", "height and width must be multiples of 16")
    b = cfg["benchmarks"]
    for size in b["train_sizes"]:
        if list(size) not in sizes:
            raise ConfigError(
                "benchmarks.train_sizes", f"{size} is not one of dataset.sizes {sizes}"
            )
        if size[0] % 16 or size[1] % 16:
            raise ConfigError(
                "benchmarks.train_sizes", f"{size}: height and width must be multiples of 16"
            )
    if b["latency_model"] not in cfg["train"]["models"]:
        raise ConfigError(
            "benchmarks.latency_model",
            (
                f"'{b['latency_model']}' is not a key of train.models {sorted(cfg['train']['models'])}"
            ),
        )


def read_config_file(path: str | Path) -> dict:
    """The YAML mapping of a config file (its ``extends`` resolved: :func:`resolve_extends`),
    not validated; :class:`ConfigError` when the file is missing, a folder, not UTF-8, not
    YAML, empty or not a mapping."""
    path = Path(path)
    return resolve_extends(read_config_file_raw(path), path.parent)


def read_config_file_raw(path: str | Path) -> dict:
    """The YAML mapping of a config file as written (see :func:`read_config_file`)."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError("<config>", f"'{path}' is a folder, not a config file")
    if not path.is_file():
        raise ConfigError("<config>", f"config file '{path}' does not exist")
    try:
        raw = yaml.safe_load(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise ConfigError(
            "<config>",
            f"'{path}' is not UTF-8 text (byte {exc.start}: "
            f"{exc.object[exc.start : exc.start + 1]!r})",
        ) from None
    except yaml.YAMLError as exc:
        raise ConfigError("<config>", f"'{path}' is not valid YAML ({exc})".replace("\n", " "))
    if raw is None:
        raise ConfigError(
            "<config>",
            f"'{path}' is empty: give the config's keys, or leave --config out for the defaults",
        )
    if not isinstance(raw, dict):
        raise ConfigError("<config>", f"'{path}' is not a mapping of config keys")
    return raw


def typed_overrides(value):
    """Snakemake's ``--config key={a: 1}`` values typed as YAML types them: Snakemake
    reads a nested value with YAML's base loader, every scalar a string, so that
    ``train={lr: 0.0001}`` gave the string '0.0001'. Strings are read again as YAML
    scalars (numbers such as 1e-4 too); mappings and lists recursively."""
    if isinstance(value, dict):
        return {k: typed_overrides(v) for k, v in value.items()}
    if isinstance(value, list):
        return [typed_overrides(v) for v in value]
    if not isinstance(value, str):
        return value
    try:
        out = yaml.safe_load(value)
    except yaml.YAMLError:
        return value
    if isinstance(out, str):
        try:
            return (
                float(out) if out.strip().lower() not in ("nan", "inf", "-inf", "infinity") else out
            )
        except ValueError:
            return value
    return out if isinstance(out, (bool, int, float)) or out is None else value


def merge_config(base: dict, over: dict) -> dict:
    """``base`` with ``over`` on top: mappings merged key by key (recursively), any other
    value (lists included) replaced, as Snakemake merges ``--configfile a b``."""
    out = copy.deepcopy(base)
    for k, v in over.items():
        out[k] = (
            merge_config(out[k], v)
            if isinstance(v, dict) and isinstance(out.get(k), dict)
            else copy.deepcopy(v)
        )
    return out


#: keys of a whole config: a file with none of them holds changes to the defaults
WHOLE_KEYS = ("finger", "objects")


def is_partial(raw: dict) -> bool:
    """Whether a config mapping holds only changes (no ``extends`` and none of
    :data:`WHOLE_KEYS`): it is read on top of ``config/config.yaml``."""
    return "extends" not in raw and not any(k in raw for k in WHOLE_KEYS)


def resolve_extends(raw: dict, folder: str | Path, seen: tuple = ()) -> dict:
    """A config that ``extends: <file>`` (relative to ``folder``, the config's own): that
    file's config (itself resolved) with this one's keys on top (:func:`merge_config`),
    so that a variant of a config holds only what differs. A config of changes only
    (:func:`is_partial`) extends the source tree's ``config/config.yaml``. Unchanged
    otherwise."""
    if is_partial(raw) and not seen:
        base = default_config_path()
        if not base.is_file():
            raise ConfigError(
                "<config>",
                "the config names none of finger, objects (changes only) and there is no "
                "config/config.yaml here to change: add 'extends: <path to config.yaml>'",
            )
        return merge_config(read_config_file_raw(base), raw)
    if "extends" not in raw:
        return raw
    base_path = Path(folder) / str(raw["extends"])
    if base_path.resolve() in seen:
        raise ConfigError("extends", f"'{base_path}' extends itself (through {len(seen)} file(s))")
    base = read_config_file_raw(base_path)
    base = resolve_extends(base, base_path.parent, seen + (base_path.resolve(),))
    return merge_config(base, {k: v for k, v in raw.items() if k != "extends"})


def load_config(path: str | Path) -> dict:
    """Read and validate a YAML config file."""
    return validate_config(read_config_file(path), base_dir=Path.cwd())


def default_config_path() -> Path:
    """``config/config.yaml`` of the source tree, if the package runs from it."""
    return Path(__file__).resolve().parents[2] / "config" / "config.yaml"


@dataclass(frozen=True)
class Scene:
    """One finger x object x material x contact height."""

    object: str
    material: str
    height_mm: float
    split: str

    @property
    def id(self) -> str:
        return f"{self.object}_{self.material}_h{self.height_mm:g}"


def object_is_meshed(cfg: dict, name: str) -> bool:
    """Deformable objects are meshed; purely rigid ones stay boundaries."""
    return any(not cfg["materials"][m]["rigid"] for m in cfg["objects"][name]["materials"])


def sim2real_model_name(cfg: dict) -> str:
    """The model sim-to-real starts from: camera where train.models has it, else plain."""
    return "camera" if "camera" in cfg["train"]["models"] else "plain"


def extra_train_heights(cfg: dict, model: str | None = None) -> list[float]:
    """Contact heights (mm) beyond ``heights_mm`` at which the training objects are also
    simulated and rendered: those of ``model`` in ``extra_train_heights_mm``, or of every
    model (``None``), sorted."""
    extra = cfg.get("extra_train_heights_mm", {})
    picked = extra.values() if model is None else [extra.get(model, [])]
    return sorted({float(h) for hs in picked for h in hs} - {float(h) for h in cfg["heights_mm"]})


@functools.lru_cache(maxsize=None)
def _lowest_point_mm(spec_json: str, size_mm: float) -> float:
    """y (mm) of an object's lowest point relative to its reference point."""
    return float(object_shape(json.loads(spec_json), size_mm).bounds[1])


def face_heights(cfg: dict, name: str) -> list[float]:
    """Contact heights (mm) of ``face_heights_mm`` for object ``name``'s split, beyond
    ``heights_mm`` and the extra training heights, at which the object stays above the
    clamped base (its lowest point at y >= 0), sorted."""
    spec = cfg["objects"][name]
    hs = cfg.get("face_heights_mm", {}).get(spec["split"], [])
    if not hs:
        return []
    low = _lowest_point_mm(json.dumps(spec, sort_keys=True), float(cfg["mesh"]["size_mm"]))
    known = {float(h) for h in cfg["heights_mm"]}
    if spec["split"] == "train":
        known |= set(extra_train_heights(cfg))
    return sorted({float(h) for h in hs if h + low >= 0} - known)


def object_heights(cfg: dict, name: str) -> list[float]:
    """Every contact height (mm) of object ``name``: ``heights_mm``, then (training
    objects) :func:`extra_train_heights`, then :func:`face_heights`."""
    split = cfg["objects"][name]["split"]
    extra = extra_train_heights(cfg) if split == "train" else []
    return [*(float(h) for h in cfg["heights_mm"]), *extra, *face_heights(cfg, name)]


def scenes(cfg: dict) -> list[Scene]:
    """Every scene of the config: every object at each of :func:`object_heights` (every
    height of ``heights_mm``; the training objects' extra heights; the face heights of
    the object's split)."""
    return [
        Scene(name, m, h, spec["split"])
        for name, spec in cfg["objects"].items()
        for m in spec["materials"]
        for h in object_heights(cfg, name)
    ]
