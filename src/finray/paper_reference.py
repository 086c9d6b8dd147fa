"""The paper's reference numbers (``paper_reference.yaml``): one home for every value
the manuscript, the speed table and the figures compare against, each with its unit
and where the paper states it. It imports no stage, so any stage may read it."""

from __future__ import annotations

import copy
from functools import lru_cache
from pathlib import Path

import yaml

PATH = Path(__file__).with_name("paper_reference.yaml")


@lru_cache(maxsize=1)
def _load() -> dict:
    return yaml.safe_load(PATH.read_text())


def paper_reference() -> dict:
    """``{"source": str, "values": {name: {"value", "unit", "where", "quote"}}}`` (a copy)."""
    return copy.deepcopy(_load())


def paper_value(name: str):
    """One reference value, e.g. ``paper_value("network_ms_per_frame_gpu")`` -> 8.0."""
    values = _load()["values"]
    if name not in values:
        raise KeyError(f"no paper reference value {name!r}; known: {', '.join(values)}")
    return copy.deepcopy(values[name]["value"])
