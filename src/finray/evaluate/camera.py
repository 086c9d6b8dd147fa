"""The camera path scored against the FEA: rendered full frames (PNG) through
:class:`~finray.predict.Predictor`'s own preprocessing (segment the whole frame,
crop anchored on the finger's base, area-resample), not the dataset shards' inputs
(segmented and cropped with the renderer's known window).

Only frames written as files are scored (``render.files_per_scene`` per view, first
and last included); their FEA force comes from the render's ``index.json`` (the
same value the shard holds for that frame) and their stress target from the
frame's EXR (``coverage``, ``stress_area``) resampled over the predictor's crop,
so that the stress metrics compare maps on the same pixels as the input.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from ..dataset import area_resample, scene_id
from ..dataset.shards import HALF
from ..errors import FrameError
from ..predictor import Predictor
from ..render import load_render_index, read_render_frame


def camera_test_set(index_paths, predictor: Predictor) -> tuple[dict, pd.DataFrame]:
    """Network inputs of every rendered frame with files, through ``predictor``'s
    preprocessing, and their FEA targets, as :func:`~finray.evaluate.predictions.load_test_set`
    gives them for shards: arrays ``images`` (N, H, W) uint8 (the predictor's input
    x255, exact: it is 8-bit), ``stress`` (N, H, W) float32 log-stress, ``mask``
    (N, H, W) bool (silhouette covers >= half the pixel), ``fx_N`` (N,) N; a table
    with scene_id, object, material, height_mm, pitch_deg, frame, displacement_mm,
    fx_N, fy_N. Raises ValueError naming the file for a frame the predictor cannot read."""
    images, stress, masks, rows = [], [], [], []
    for path in sorted(str(p) for p in index_paths):
        render_dir = Path(path).parent
        index = load_render_index(render_dir)
        sc = dict(index.get("scene") or {})
        sc["pitch_deg"] = float(index["pitch_deg"])
        sid = scene_id(sc)
        for fr in index["frames"]:
            if fr.get("image") is None:
                continue
            rgb, maps = read_render_frame(render_dir, fr["frame"], index)
            try:
                mask = predictor.segment(rgb)
                box = predictor.crop_box(mask)
            except FrameError as exc:
                raise ValueError(f"{render_dir / fr['image']}: {exc}") from None
            soft = area_resample(mask, box, predictor.size, fast=True)
            images.append(np.rint(predictor.network_input(mask)[0, 0] * 255.0).astype(np.uint8))
            masks.append(soft >= HALF)
            cov = area_resample(maps["coverage"], box, predictor.size)
            area = area_resample(maps["stress_area"], box, predictor.size)
            full = cov >= HALF
            stress.append(np.where(full, area / np.where(full, cov, 1.0), 0.0).astype(np.float32))
            rows.append(
                {
                    "scene_id": sid,
                    "object": sc.get("object"),
                    "material": sc.get("material"),
                    "height_mm": float(sc.get("height_mm", np.nan)),
                    "pitch_deg": sc["pitch_deg"],
                    "frame": int(fr["frame"]),
                    "displacement_mm": float(fr["displacement_mm"]),
                    "fx_N": float(fr["fx_N"]),
                    "fy_N": float(fr["fy_N"]),
                }
            )
    if not rows:
        raise ValueError("no rendered frame has files (render.files_per_scene is 0?)")
    table = pd.DataFrame(rows)
    h, w = predictor.size
    arrays = {
        "images": np.stack(images).reshape(-1, h, w),
        "stress": np.stack(stress),
        "mask": np.stack(masks),
        "fx_N": table["fx_N"].to_numpy(),
    }
    return arrays, table


def shared_preprocessing(predictors: dict[str, Predictor]) -> Predictor:
    """The predictor whose preprocessing gives the camera inputs of all of them (the
    first); ValueError if the models were exported with different settings."""
    first_name, first = next(iter(predictors.items()))
    ref = (first.size, json.dumps(first.meta.get("preprocess", {}), sort_keys=True))
    for name, p in predictors.items():
        if (p.size, json.dumps(p.meta.get("preprocess", {}), sort_keys=True)) != ref:
            raise ValueError(
                f"camera path: models {first_name} and {name} preprocess frames "
                "differently (input size or model.ts.json 'preprocess')"
            )
    return first


def rendered_subset(table: pd.DataFrame, camera: pd.DataFrame) -> np.ndarray:
    """Rows (bool) of the shard ``table`` that are frames of the ``camera`` table;
    ValueError if a camera frame is not in the shards or its FEA force differs (the
    renders and the shards are not of the same run)."""
    key = pd.MultiIndex.from_frame(table[["scene_id", "frame"]])
    ckey = pd.MultiIndex.from_frame(camera[["scene_id", "frame"]])
    missing = ~ckey.isin(key)
    if missing.any():
        sid, fr = ckey[np.flatnonzero(missing)[0]]
        raise ValueError(
            f"camera path: rendered frame {fr} of {sid} is not in the test shards "
            f"({int(missing.sum())} such frames)"
        )
    sel = key.isin(ckey)
    shard_fx = pd.Series(table["fx_N"].to_numpy()[sel], index=key[sel])
    diff = np.abs(shard_fx.loc[ckey].to_numpy() - camera["fx_N"].to_numpy())
    if diff.max() > 1e-9 * max(1.0, float(np.abs(camera["fx_N"]).max())):
        i = int(diff.argmax())
        raise ValueError(
            f"camera path: FEA force of frame {ckey[i][1]} of {ckey[i][0]} differs "
            f"between its render index and its shard by {diff[i]:.3g} N "
            "(renders and shards of different runs)"
        )
    return sel
