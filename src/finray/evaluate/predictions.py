"""Test sets from dataset shards and batched predictions of an exported model."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..dataset import apply_augment, augment_seed, load_frames, sample_augment
from ..schema import schema_default


def load_test_set(shard_paths, size: tuple[int, int]) -> tuple[dict, pd.DataFrame]:
    """Arrays at one input size and a per-frame table of the shards, in path order
    (:func:`finray.dataset.load_frames`: ``images`` uint8, ``stress``, ``mask``,
    ``fx_N``; columns scene_id, object, material, height_mm, pitch_deg, frame,
    displacement_mm, fx_N)."""
    return load_frames(sorted(str(p) for p in shard_paths), size)


def occlude(
    images: np.ndarray,
    table: pd.DataFrame,
    level: str,
    seed: int,
    occlusion_levels: dict | None = None,
    occluder_value: float = schema_default("dataset.occluder_value"),
) -> np.ndarray:
    """Every image occluded by a disc of the level, replayable from
    ``augment_seed(seed, scene_id, frame, level)``."""
    if level == "none":
        return images
    out = np.empty_like(images)
    shape = images.shape[1:]
    for i, (sid, fr) in enumerate(zip(table["scene_id"], table["frame"])):
        p = sample_augment(
            augment_seed(seed, sid, int(fr), level),
            shape,
            occlusion=level,
            occlusion_levels=occlusion_levels,
        )
        out[i] = apply_augment(images[i], p, occluder_value)
    return out


def predict_images(predictor, images: np.ndarray, batch: int = 256, contact: bool = False):
    """Forces (N, n_forces) in N (the predictor's ``force_names``: ``fx_N`` first) and
    log-stress maps (N, H, W) of network inputs (N, H, W), uint8 or [0, 1] floats,
    through :meth:`finray.predict.Predictor.run` in batches. ``contact``: also the
    contact heights (N,) in mm, a third array (NaN for a model without the contact
    head, :attr:`~finray.predict.Predictor.has_contact`)."""
    x = np.asarray(images)
    scale = 255.0 if x.dtype == np.uint8 else 1.0
    forces, maps, heights = [], [], []
    for i in range(0, len(x), batch):
        xb = x[i : i + batch, None].astype(np.float32) / scale
        if contact:
            stress, force, c = predictor.run_contact(xb)
            heights.append(c)
        else:
            stress, force = predictor.run(xb)
        forces.append(force)
        maps.append(stress[:, 0])
    out = np.concatenate(forces), np.concatenate(maps)
    return (*out, np.concatenate(heights)) if contact else out
