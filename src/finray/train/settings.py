"""A model's settings file (``model.ts.json``): its schema, its seal and its one reader.

The settings say how a frame becomes the network's input (``preprocess``: the window
around the clamped base, the segmentation) and what its outputs mean and where they
hold (``forces``, ``stress_ref_MPa``, ``trained``: the training's ranges that each
frame is checked against). A wrong value there gives a wrong force without an error,
so the file is read through :func:`read_settings` only: checked against
:data:`SETTINGS_SCHEMA` (types, finite numbers, ordered ranges) and against its own
SHA-256 (``sha256.settings``, written by :func:`finray.train.export.seal`), each failure
one line (:class:`~finray.errors.ModelError`)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from ..errors import ModelError

_NUM = {"type": "number"}
_POS = {"type": "number", "exclusiveMinimum": 0}
_FRAC = {"type": "number", "minimum": 0, "maximum": 1}
_INT1 = {"type": "integer", "minimum": 1}
#: an interval [lo, hi] (lo <= hi is checked by :func:`read_settings`)
_SPAN = {"type": "array", "items": _NUM, "minItems": 2, "maxItems": 2}
_MM = {
    "type": "array",
    "items": {"type": "number", "minimum": -1000, "maximum": 1000},
    "minItems": 2,
    "maxItems": 2,
}

SETTINGS_SCHEMA = {
    "type": "object",
    "required": ["height", "width"],
    "properties": {
        "in_channels": {"const": 1},
        "base_channels": _INT1,
        "height": {"type": "integer", "minimum": 1, "maximum": 4096},
        "width": {"type": "integer", "minimum": 1, "maximum": 4096},
        "n_forces": _INT1,
        "hidden": {"type": "array", "items": _INT1},
        "init": {"type": "string"},
        "contact": {"type": "boolean"},
        "forces": {"type": "array", "items": {"type": "string", "minLength": 1}, "minItems": 1},
        "contact_min_force_N": {"type": "number", "minimum": 0},
        "stress_ref_MPa": _POS,
        "force_normalisation": {
            "type": "object",
            "required": ["mean_N", "scale_N"],
            "properties": {
                "mean_N": {"type": "array", "items": _NUM, "minItems": 1},
                "scale_N": {"type": "array", "items": _POS, "minItems": 1},
            },
            "additionalProperties": False,
        },
        "trained": {
            "type": "object",
            "properties": {
                "n_frames": {"type": "integer", "minimum": 0},
                "fill": {**_SPAN, "items": _FRAC},
                "shape_iou_min": _FRAC,
                "silhouette": {
                    "type": "array",
                    "items": {"type": "array", "items": _FRAC, "minItems": 1},
                    "minItems": 1,
                },
                "force_N": {"type": "object", "additionalProperties": _SPAN},
                "contact_mm": _SPAN,
                "stiff_below_mm": {"type": "number", "minimum": 0, "maximum": 1000},
            },
            "required": ["fill", "shape_iou_min", "silhouette"],
            "additionalProperties": False,
        },
        "preprocess": {
            "type": "object",
            "properties": {
                "base_width_mm": {"type": "number", "exclusiveMinimum": 0, "maximum": 1000},
                "crop_x_mm": _MM,
                "crop_y_mm": _MM,
                "base_band": _FRAC,
                "segment": {
                    "type": "object",
                    "properties": {
                        "threshold": {
                            "oneOf": [{"enum": ["isodata", "otsu"]}, _FRAC],
                        },
                        "foreground": {"enum": ["bright", "dark"]},
                        "min_object_frac": _FRAC,
                        "max_hole_frac": _FRAC,
                        "keep_largest": {"type": "boolean"},
                    },
                    "additionalProperties": False,
                },
            },
            "additionalProperties": False,
        },
        "ensemble": {"type": "integer", "minimum": 0},
        "adapted": {"type": "object"},
        "sha256": {
            "type": "object",
            "additionalProperties": {"type": "string", "pattern": "^[0-9a-f]{64}$"},
        },
    },
    "additionalProperties": True,  # later versions may add keys; the known ones are typed
}


def settings_digest(meta: dict) -> str:
    """The SHA-256 (hex) of the settings without their ``sha256`` block, in canonical
    JSON (sorted keys), so that re-indenting the file keeps it and any changed value
    does not."""
    body = {k: v for k, v in meta.items() if k != "sha256"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


def check_settings_values(meta, name: str) -> None:
    """:data:`SETTINGS_SCHEMA`, finite numbers and ordered intervals, or one line."""
    import jsonschema

    from ..schema import non_finite

    if not isinstance(meta, dict):
        raise ModelError(f"{name} is not a model's settings (not a mapping)")
    err = jsonschema.exceptions.best_match(
        jsonschema.Draft202012Validator(SETTINGS_SCHEMA).iter_errors(meta)
    )
    if err is not None:
        where = "/".join(str(p) for p in err.absolute_path) or "top level"
        raise ModelError(f"{name} is not a model's settings ({where}: {err.message})")
    bad = non_finite(meta)
    if bad is not None:
        where = "/".join(str(k) for k in bad[0])
        raise ModelError(f"{name} is not a model's settings ({where}: {bad[1]}, not finite)")
    pre, trained = meta.get("preprocess", {}), meta.get("trained", {})
    spans = {f"preprocess/{k}": pre.get(k) for k in ("crop_x_mm", "crop_y_mm")}
    spans |= {f"trained/{k}": trained.get(k) for k in ("fill", "contact_mm")}
    spans |= {f"trained/force_N/{k}": v for k, v in trained.get("force_N", {}).items()}
    for where, span in spans.items():
        if span is None:
            continue
        # a crop window has a width; a training range may be one value
        if span[0] > span[1] or (where.startswith("preprocess") and span[0] == span[1]):
            raise ModelError(f"{name} is not a model's settings ({where}: {span}, lo above hi)")
    sil = trained.get("silhouette")
    if sil is not None and len({len(row) for row in sil}) != 1:
        raise ModelError(
            f"{name} is not a model's settings (trained/silhouette: rows of unequal length)"
        )


def read_settings(path: str | Path) -> tuple[dict, str | None]:
    """``model.ts.json`` checked (:func:`check_settings_values`) and against its seal:
    the settings and a note (None, or the line that says they were exported before
    their seal was kept), or a one-line :class:`~finray.errors.ModelError`."""
    path = Path(path)
    try:
        meta = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ModelError(
            f"{path} is not the model's JSON settings ({type(exc).__name__})"
        ) from None
    except OSError as exc:
        raise ModelError(f"{path} cannot be read ({exc.strerror or exc})") from None
    check_settings_values(meta, path.name)
    sealed = (meta.get("sha256") or {}).get("settings")
    if not meta.get("sha256"):  # no seal at all: check_sealed says so, for the files too
        return meta, None
    if sealed is None:
        return meta, (
            f"{path.name}: its settings carry no seal (exported before it was kept): "
            "not checked against their export"
        )
    if sealed != settings_digest(meta):
        raise ModelError(
            f"{path.name} was changed since its export (its settings' SHA-256 differs "
            "from sha256.settings); export the model again"
        )
    return meta, None
