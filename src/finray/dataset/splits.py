"""Data splits by object.

- ``train``: circles and squares (config ``objects.<name>.split: train``)
- ``shape``: held-out shapes (``split: shape``)
- ``material``: the ring in each of its materials (``split: material``)
- ``pitch``: the pitch test object (default: the first ``shape`` object of the
  config, "held-out test object 1") rendered at every pitch of ``render.pitches_deg``

Only the pitch object is rendered at pitches other than 0. Its pitch-0 frames
belong to both its own split and ``pitch`` (the manifest lists them once per
split), so ``manifest[manifest.split == "pitch"]`` is the whole pitch series.
"""

from __future__ import annotations

SPLITS = ("train", "shape", "material", "pitch")


def pitch_object(cfg: dict) -> str:
    """Name of the pitch test object: ``dataset.pitch_object`` if set, else the first
    object of the config whose split is ``shape``."""
    name = (cfg.get("dataset") or {}).get("pitch_object")
    if name:
        if name not in cfg["objects"]:
            raise ValueError(f"dataset.pitch_object: '{name}' is not a key of objects")
        return name
    for obj, spec in cfg["objects"].items():
        if spec.get("split", "train") == "shape":
            return obj
    raise ValueError("dataset.pitch_object: no object has split 'shape'; name one explicitly")


def scene_splits(object_split: str, pitch_deg: float, is_pitch_object: bool) -> list[str]:
    """The splits a rendered scene belongs to (first = its primary split)."""
    if object_split not in SPLITS[:3]:
        raise ValueError(f"unknown split {object_split!r}")
    if not is_pitch_object:
        if pitch_deg != 0:
            raise ValueError("only the pitch test object is rendered at a pitch other than 0")
        return [object_split]
    return [object_split, "pitch"] if pitch_deg == 0 else ["pitch"]
