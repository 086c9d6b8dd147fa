"""The config schema: the one home of every config key's default and meaning.

``workflow/schemas/config.schema.yaml`` ships inside the package as
``finray/config.schema.yaml``. The dataclasses that read a config section take their
defaults from it with :func:`schema_default`, so that a default is written once: a
class built without arguments is the class built from the schema's defaults.
"""

from __future__ import annotations

import copy
import functools
import math
from importlib import resources

import yaml


@functools.cache
def _schema() -> dict:
    with resources.files("finray").joinpath("config.schema.yaml").open() as f:
        return yaml.load(f, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))


def load_schema() -> dict:
    """The config's JSON schema (a copy: the caller may change it)."""
    return copy.deepcopy(_schema())


def schema_node(path: str) -> dict:
    """The schema of the config key at the dotted ``path`` (e.g. ``"render.px_per_mm"``);
    ``KeyError`` naming the path when there is no such key."""
    node = _schema()
    for part in path.split("."):
        try:
            node = node["properties"][part]
        except KeyError:
            raise KeyError(f"{path}: not a key of the config schema") from None
    return node


def frozen(value):
    """``value`` with every list a tuple (recursively): a dataclass field's default."""
    if isinstance(value, list):
        return tuple(frozen(v) for v in value)
    if isinstance(value, dict):
        return {k: frozen(v) for k, v in value.items()}
    return value


def schema_default(path: str, convert=frozen):
    """The schema's default of the config key at ``path``, through ``convert`` (lists
    become tuples unless told otherwise); ``KeyError`` when the key has no default."""
    node = schema_node(path)
    if "default" not in node:
        raise KeyError(f"{path}: the config schema gives no default")
    return convert(copy.deepcopy(node["default"]))


def non_finite(value, path: tuple = ()) -> tuple[tuple, float] | None:
    """``(path, value)`` of the first NaN or infinite float in ``value`` (a config or any
    JSON value, walked); None where there is none. JSON schema's ``type: number`` takes
    NaN, and NaN passes every ``minimum`` and ``maximum``."""
    if isinstance(value, float) and not math.isfinite(value):
        return path, value
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, (list, tuple)):
        items = enumerate(value)
    else:
        return None
    for k, v in items:
        found = non_finite(v, path + (k,))
        if found is not None:
            return found
    return None
