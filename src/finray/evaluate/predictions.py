"""Test sets from dataset shards and batched predictions of an exported model."""
from __future__ import annotations

import numpy as np
import pandas as pd

from ..dataset import apply_augment, augment_seed, load_shard, sample_augment, size_key


def load_test_set(shard_paths, size: tuple[int, int]) -> tuple[dict, pd.DataFrame]:
    """Arrays at one input size and a per-frame table.

    Arrays: ``images`` (N, H, W) uint8 (the soft silhouette x255), ``stress`` (N, H, W)
    float32 log-stress, ``mask`` (N, H, W) bool, ``fx_N`` (N,). Table columns:
    scene_id, object, material, height_mm, pitch_deg, frame, displacement_mm, fx_N.
    """
    k = size_key(size)
    arrays = {"images": [], "stress": [], "mask": [], "fx_N": []}
    rows = []
    for path in sorted(str(p) for p in shard_paths):
        d = load_shard(path)
        sc = d["meta"]["scene"]
        arrays["images"].append(d[f"input_{k}"])
        arrays["stress"].append(d[f"stress_{k}"])
        arrays["mask"].append(d[f"mask_{k}"].astype(bool))
        arrays["fx_N"].append(d["fx_N"])
        rows.append(pd.DataFrame({
            "scene_id": sc["scene_id"], "object": sc["object"], "material": sc["material"],
            "height_mm": float(sc["height_mm"]), "pitch_deg": float(sc["pitch_deg"]),
            "frame": d["frame"], "displacement_mm": d["displacement_mm"], "fx_N": d["fx_N"]}))
    if not rows:
        raise ValueError("no shards given")
    return {n: np.concatenate(v) for n, v in arrays.items()}, pd.concat(rows, ignore_index=True)


def occlude(images: np.ndarray, table: pd.DataFrame, level: str, seed: int,
            occlusion_levels: dict | None = None, occluder_value: float = 0.0) -> np.ndarray:
    """Every image occluded by a disc of the level, replayable from
    ``augment_seed(seed, scene_id, frame, level)``."""
    if level == "none":
        return images
    out = np.empty_like(images)
    shape = images.shape[1:]
    for i, (sid, fr) in enumerate(zip(table["scene_id"], table["frame"])):
        p = sample_augment(augment_seed(seed, sid, int(fr), level), shape, occlusion=level,
                           occlusion_levels=occlusion_levels)
        out[i] = apply_augment(images[i], p, occluder_value)
    return out


def predict_images(predictor, images: np.ndarray, batch: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """Force (N,) in N and log-stress maps (N, H, W) of network inputs (N, H, W), uint8
    or [0, 1] floats, through :meth:`finray.predict.Predictor.run` in batches."""
    x = np.asarray(images)
    scale = 255.0 if x.dtype == np.uint8 else 1.0
    forces, maps = [], []
    for i in range(0, len(x), batch):
        stress, force = predictor.run(x[i:i + batch, None].astype(np.float32) / scale)
        forces.append(force[:, 0])
        maps.append(stress[:, 0])
    return np.concatenate(forces), np.concatenate(maps)
