"""The paper's simulation experiments: predictions of the network(s) and the ridge
baseline on a test set, per condition, with force and stress metrics.

Every experiment writes into one directory:

- ``frames.csv``: one row per test frame, condition and ``path`` (scene, frame,
  displacement, FEA force ``fx_N`` and one ``pred_<predictor>`` column per predictor);
  ``path`` is ``shard`` (the dataset shards' inputs) or ``camera`` (the rendered full
  frames through :class:`~finray.predict.Predictor`, see :mod:`finray.evaluate.camera`;
  when render indices are given);
- ``metrics.csv``: force metrics (:func:`~finray.evaluate.metrics.force_metrics`) per
  condition, ``path``, ``frames`` and predictor, with ``group == "all"`` for the
  condition as a whole and one row per object (or material, height...) otherwise;
  stress metrics (log-stress MSE inside the silhouette mask, SSIM) for the networks.
  ``frames`` is ``all`` (every test frame) or ``rendered`` (only the frames written
  as files, the camera path's: the shard path on them compares like for like);
- ``metrics.json``: ``{condition: {predictor: metrics of "all"}}`` for the summary
  (shard path, all frames), plus ``"<predictor>/camera"`` and
  ``"<predictor>/shard_rendered"`` when the camera path ran;
- ``heights.csv``: force metrics per contact height of the test scenes and predictor
  (shard path), each height's 10 mm band and whether a training scene used it
  (:func:`_height_rows`; empty for the viewpoint experiment);
- ``examples.npz``: a few frames (input, FEA and predicted stress) for the figures;
- ``checks.json`` (written by the rule's script): experiment-specific checks, e.g. for
  the pitch study the IoU of the pitch augmentation against the pitched renders.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pandas as pd

from .baseline import RidgeBaseline
from .camera import camera_test_set, rendered_subset, shared_preprocessing
from .metrics import (
    CONTACT_MIN_FORCE_N,
    contact_metrics,
    force_metrics,
    force_vector_metrics,
    stress_metrics,
)
from ..dataset import scene_id
from ..errors import FrameError
from ..predictor import Predictor
from .predictions import load_test_set, occlude, predict_images
from .tables import PATH_KEYS


def _predict_all(images_u8, models: dict[str, Predictor], baseline: RidgeBaseline | None):
    """``({predictor: forces (N, k) N, fx first}, {network: stress maps}, {network:
    contact heights (N,) mm, of the networks with a contact head})``."""
    preds, maps, contact = {}, {}, {}
    for name, m in models.items():
        if m.has_contact:
            preds[name], maps[name], contact[name] = predict_images(m, images_u8, contact=True)
        else:
            preds[name], maps[name] = predict_images(m, images_u8)
    if baseline is not None:
        preds["baseline"] = baseline.predict_images(images_u8.astype(np.float32) / 255.0)[:, None]
    return preds, maps, contact


def _add_predictions(frames: pd.DataFrame, preds: dict, contact: dict | None = None) -> None:
    """``pred_<p>`` (fx, N) per predictor, ``pred_fy_<p>`` for those predicting fy and
    ``contact_pred_<p>`` (mm) for those predicting the contact height."""
    for p, v in preds.items():
        frames[f"pred_{p}"] = v[:, 0]
        if v.shape[1] > 1:
            frames[f"pred_fy_{p}"] = v[:, 1]
    for p, v in (contact or {}).items():
        frames[f"contact_pred_{p}"] = v


def _contact_row(frames: pd.DataFrame, p: str, sel) -> dict:
    """Contact-height metrics (mm) of predictor ``p`` on the selected frames with
    |Fx| > CONTACT_MIN_FORCE_N, where it predicts the height and the frames know it."""
    if f"contact_pred_{p}" not in frames or "contact_y_mm" not in frames:
        return {}
    m = contact_metrics(
        frames["contact_y_mm"][sel],
        frames[f"contact_pred_{p}"][sel],
        frames["fx_N"][sel],
        CONTACT_MIN_FORCE_N,
    )
    return {"contact_rmse_mm": m["rmse_mm"], "contact_mae_mm": m["mae_mm"], "contact_n": m["n"]}


def _metric_rows(
    frames: pd.DataFrame,
    group_col: str | None,
    condition: str,
    predictors,
    stress: dict | None = None,
    path: str = "shard",
    subset: str = "all",
) -> list[dict]:
    """Force (and stress) metrics over the condition and per value of ``group_col``."""
    groups = [("all", np.ones(len(frames), bool))]
    if group_col:
        groups += [
            (str(g), (frames[group_col] == g).to_numpy())
            for g in sorted(frames[group_col].unique())
        ]
    rows = []
    for gname, sel in groups:
        for p in predictors:
            row = {
                "condition": condition,
                "path": path,
                "frames": subset,
                "group": gname,
                "predictor": p,
                **force_metrics(frames["fx_N"][sel], frames[f"pred_{p}"][sel]),
            }
            row.update(_contact_row(frames, p, sel))
            if f"pred_fy_{p}" in frames:
                row.update(
                    force_vector_metrics(
                        frames["fx_N"][sel],
                        frames["fy_N"][sel],
                        frames[f"pred_{p}"][sel],
                        frames[f"pred_fy_{p}"][sel],
                    )
                )
            if stress is not None and p in stress["pred"]:
                row.update(
                    stress_metrics(stress["true"][sel], stress["pred"][p][sel], stress["mask"][sel])
                )
            rows.append(row)
    return rows


def _height_rows(
    frames: pd.DataFrame, condition: str, predictors, train_heights_mm=()
) -> list[dict]:
    """Force metrics per contact height of the test scenes (RMSE in N; NRMSE in % of the
    largest |Fx| at that height, since the force near the base is many times the force
    at the tip), each height with its 10 mm band (``band_mm``: the band's lower edge) and
    whether any training scene used it (``unseen``)."""
    seen = {round(float(h), 6) for h in train_heights_mm}
    rows = []
    heights = frames["height_mm"].to_numpy(dtype=float)
    for h in np.unique(heights):
        sel = heights == h
        for p in predictors:
            rows.append(
                {
                    "condition": condition,
                    "height_mm": float(h),
                    "band_mm": float(10 * np.floor(h / 10)),
                    "unseen": round(float(h), 6) not in seen,
                    "predictor": p,
                    **force_metrics(frames["fx_N"][sel], frames[f"pred_{p}"][sel]),
                    **_contact_row(frames, p, sel),
                }
            )
    return rows


#: Columns that name a metrics row (the rest are metrics).
ID_COLUMNS = ("condition", "path", "frames", "group", "predictor")
#: Columns that name a row of ``heights.csv``.
HEIGHT_COLUMNS = ["condition", "height_mm", "band_mm", "unseen", "predictor"]


def _variant(row: dict) -> str:
    """Key of a metrics row's predictor in ``metrics.json``: the predictor's name for the
    shard path on all frames, ``<predictor>/<path key>`` otherwise (see PATH_KEYS)."""
    key = PATH_KEYS[(row.get("path", "shard"), row.get("frames", "all"))]
    return row["predictor"] if key is None else f"{row['predictor']}/{key}"


def _camera_rows(
    render_indices, nets, base, tab, fr, stress, maps, group_col, cname, predictors, frames_out, log
) -> list[dict]:
    """Metrics of the camera path on the rendered frames and of the shard path on the
    same frames; the camera frames are appended to ``frames_out``."""
    t0 = time.perf_counter()
    arrays, ctab = camera_test_set(render_indices, shared_preprocessing(nets))
    sel = rendered_subset(tab, ctab)
    preds, cmaps, ccontact = _predict_all(arrays["images"], nets, base)
    cfr = ctab.copy()
    cfr.insert(0, fr.columns[0], cname)  # the condition column
    cfr.insert(1, "path", "camera")
    _add_predictions(cfr, preds, ccontact)
    frames_out.append(cfr)
    rows = _metric_rows(
        fr[sel].reset_index(drop=True),
        group_col,
        cname,
        predictors,
        {
            "true": stress["true"][sel],
            "mask": stress["mask"][sel],
            "pred": {k: v[sel] for k, v in maps.items()},
        },
        "shard",
        "rendered",
    )
    rows += _metric_rows(
        cfr,
        group_col,
        cname,
        predictors,
        {"true": arrays["stress"], "mask": arrays["mask"], "pred": cmaps},
        "camera",
        "rendered",
    )
    log(
        f"{cname}: camera path on {len(ctab)} rendered frames of {len(render_indices)} views "
        f"in {time.perf_counter() - t0:.2f} s"
    )
    return rows


def _write_outputs(
    out_dir: Path,
    rows: list[dict],
    frames_out: list[pd.DataFrame],
    examples: dict,
    height_rows: list[dict] = (),
) -> pd.DataFrame:
    """Write ``frames.csv``, ``metrics.csv``, ``metrics.json`` (per condition, in the
    order of ``examples``), ``heights.csv`` (:func:`_height_rows`) and ``examples.npz``;
    returns the metrics table."""
    metrics = pd.DataFrame(rows)
    pd.DataFrame(list(height_rows), columns=HEIGHT_COLUMNS if not height_rows else None).to_csv(
        out_dir / "heights.csv", index=False, float_format="%.10g"
    )
    pd.concat(frames_out, ignore_index=True).to_csv(
        out_dir / "frames.csv", index=False, float_format="%.6g"
    )
    metrics.to_csv(out_dir / "metrics.csv", index=False, float_format="%.10g")
    summary = {
        c: {
            _variant(r): {k: r[k] for k in r if k not in ID_COLUMNS}
            for r in rows
            if r["condition"] == c and r["group"] == "all"
        }
        for c in examples
    }
    (out_dir / "metrics.json").write_text(json.dumps(summary, indent=1))
    np.savez_compressed(
        out_dir / "examples.npz",
        **{f"{c}/{k}": v for c, d in examples.items() for k, v in d.items()},
    )
    return metrics


def _example_indices(table: pd.DataFrame, per: str, n: int = 1) -> np.ndarray:
    """Per value of ``per``: the frame of largest FEA force (where stress shows most)."""
    idx = []
    for _, g in table.groupby(per, sort=True):
        idx += list(g["fx_N"].nlargest(n).index)
    return np.asarray(idx, dtype=int)


def run_experiment(
    out_dir,
    shard_paths,
    size,
    models: dict[str, str],
    baseline_path=None,
    *,
    conditions: dict[str, dict] | None = None,
    condition_col: str = "condition",
    group_col: str | None = "object",
    occlusion_levels: dict | None = None,
    seed: int = 0,
    render_indices=None,
    train_heights_mm=(),
    log=print,
) -> pd.DataFrame:
    """Evaluate ``models`` (name -> TorchScript path) and the baseline on the shards.

    ``conditions``: name -> ``{"occlusion": level}`` (images corrupted, replayable from
    ``seed``) or ``{"pitch_deg": p}`` (frames of that pitch only); default: one condition
    ``"all"`` over every frame. ``render_indices`` (the test scenes' ``index.json``):
    also score the camera path on their rendered frames, and the shard path on the same
    frames, for every condition without corruption or selection. ``train_heights_mm``:
    the training scenes' contact heights, which ``heights.csv`` tells apart from the
    unseen ones. Returns the metrics table (also written).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    arrays, table = load_test_set(shard_paths, size)
    # TorchScript: batched, and the same runtime as the training's export
    nets = {
        name: Predictor(path, threads=1, backend="torchscript", roi_stride=1)
        for name, path in models.items()
    }
    base = RidgeBaseline.load(baseline_path) if baseline_path else None
    predictors = list(nets) + (["baseline"] if base is not None else [])
    conditions = conditions or {"all": {}}
    frames_out, rows, examples, height_rows = [], [], {}, []
    for cname, cond in conditions.items():
        sel = np.ones(len(table), bool)
        if "pitch_deg" in cond:
            sel = np.isclose(table["pitch_deg"].to_numpy(), float(cond["pitch_deg"]))
        tab = table[sel].reset_index(drop=True)
        images = arrays["images"][sel]
        if cond.get("occlusion", "none") != "none":
            images = occlude(images, tab, cond["occlusion"], seed, occlusion_levels)
        log(f"{cname}: {len(tab)} frames, predictors {predictors}")
        preds, maps, contact = _predict_all(images, nets, base)
        fr = tab.copy()
        fr.insert(0, condition_col, cname)
        _add_predictions(fr, preds, contact)
        stress = {"true": arrays["stress"][sel], "mask": arrays["mask"][sel], "pred": maps}
        rows += _metric_rows(fr, group_col, cname, predictors, stress)
        height_rows += _height_rows(fr, cname, predictors, train_heights_mm)
        fr.insert(1, "path", "shard")
        frames_out.append(fr)
        if render_indices and not cond:
            rows += _camera_rows(
                render_indices,
                nets,
                base,
                tab,
                fr,
                stress,
                maps,
                group_col,
                cname,
                predictors,
                frames_out,
                log,
            )
        ex = _example_indices(tab, group_col or "scene_id")
        examples[cname] = {
            "input": images[ex],
            "stress_true": stress["true"][ex],
            "mask": stress["mask"][ex],
            **{f"stress_{k}": v[ex] for k, v in maps.items()},
            "label": tab[group_col or "scene_id"].to_numpy()[ex].astype(str),
            "fx_N": tab["fx_N"].to_numpy()[ex],
            **{f"pred_{k}": v[ex, 0] for k, v in preds.items()},
        }
    return _write_outputs(out_dir, rows, frames_out, examples, height_rows)


def viewpoint_test_set(
    index_paths, shard_paths, predictor: Predictor, size
) -> tuple[dict, pd.DataFrame]:
    """The viewpoint experiment's frames (:func:`finray.render.viewpoint.render_viewpoint`)
    through ``predictor``'s preprocessing (segment, base-anchored crop, resample), with
    their targets: the FEA forces of the render index and the front-view stress map
    and mask of the same frame in the scene's shard (the canonical target). Arrays as
    :func:`~finray.evaluate.predictions.load_test_set`; the table also has
    ``distance_mm``."""
    from ..render.imageio import read_png

    arrays, table = load_test_set(shard_paths, size)
    row_of = {
        (sid, int(fr)): i for i, (sid, fr) in enumerate(zip(table["scene_id"], table["frame"]))
    }
    images, idx, rows = [], [], []
    for path in sorted(str(p) for p in index_paths):
        index = json.loads(Path(path).read_text())
        sc = dict(index["scene"])
        sid = scene_id({**sc, "pitch_deg": 0.0})
        for fr in index["frames"]:
            key = (sid, fr["frame"])
            if key not in row_of:
                raise ValueError(
                    f"viewpoint: frame {fr['frame']} of {sid} is not in the test shards"
                )
            i = row_of[key]
            if abs(table.at[i, "fx_N"] - fr["fx_N"]) > 1e-9 * max(1.0, abs(fr["fx_N"])):
                raise ValueError(
                    f"viewpoint: FEA force of frame {fr['frame']} of {sid} differs between "
                    "its render and its shard (renders and shards of different runs)"
                )
            png = Path(path).parent / fr["image"]
            try:
                x = predictor.network_input(predictor.segment(read_png(png)))
            except FrameError as exc:
                raise ValueError(f"{png}: {exc}") from None
            images.append(np.rint(x[0, 0] * 255.0).astype(np.uint8))
            idx.append(i)
            rows.append(
                {
                    **{c: table.at[i, c] for c in table.columns},
                    "pitch_deg": fr["pitch_deg"],
                    "distance_mm": fr["distance_mm"],
                }
            )
    if not rows:
        raise ValueError("viewpoint: no rendered frames")
    idx = np.asarray(idx)
    out = {
        "images": np.stack(images),
        "stress": arrays["stress"][idx],
        "mask": arrays["mask"][idx],
        "fx_N": arrays["fx_N"][idx],
    }
    return out, pd.DataFrame(rows)


def run_viewpoint(
    out_dir,
    index_paths,
    shard_paths,
    size,
    models: dict[str, str],
    baseline_path=None,
    *,
    log=print,
) -> pd.DataFrame:
    """The viewpoint experiment: every model (and the baseline) on the perspective
    renders of the held-out scenes, through the predictor's preprocessing; one condition
    per pitch (named by it), groups by camera distance. Writes what :func:`run_experiment`
    writes (``path`` camera, ``frames`` all) and returns the metrics table."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    nets = {
        name: Predictor(path, threads=1, backend="torchscript", roi_stride=1)
        for name, path in models.items()
    }
    base = RidgeBaseline.load(baseline_path) if baseline_path else None
    predictors = list(nets) + (["baseline"] if base is not None else [])
    t0 = time.perf_counter()
    arrays, table = viewpoint_test_set(index_paths, shard_paths, shared_preprocessing(nets), size)
    log(
        f"viewpoint: {len(table)} rendered frames through the predictor in {time.perf_counter() - t0:.1f} s"
    )
    preds, maps, _ = _predict_all(arrays["images"], nets, base)
    rows, frames_out, examples = [], [], {}
    for p in sorted(table["pitch_deg"].unique()):
        sel = (table["pitch_deg"] == p).to_numpy()
        cname = f"{p:g}"
        fr = table[sel].reset_index(drop=True)
        fr.insert(0, "condition", cname)
        fr.insert(1, "path", "camera")
        _add_predictions(fr, {k: v[sel] for k, v in preds.items()})
        stress = {
            "true": arrays["stress"][sel],
            "mask": arrays["mask"][sel],
            "pred": {k: v[sel] for k, v in maps.items()},
        }
        rows += _metric_rows(fr, "distance_mm", cname, predictors, stress, "camera", "all")
        frames_out.append(fr)
        ex = _example_indices(fr, "distance_mm")
        examples[cname] = {
            "input": arrays["images"][sel][ex],
            "stress_true": stress["true"][ex],
            "mask": stress["mask"][ex],
            **{f"stress_{k}": v[ex] for k, v in stress["pred"].items()},
            "label": fr["distance_mm"].to_numpy()[ex].astype(str),
            "fx_N": fr["fx_N"].to_numpy()[ex],
            **{f"pred_{k}": v[sel][ex, 0] for k, v in preds.items()},
        }
    return _write_outputs(out_dir, rows, frames_out, examples)


def load_examples(path) -> dict[str, dict[str, np.ndarray]]:
    """``examples.npz`` back as ``{condition: {array name: array}}``."""
    out: dict[str, dict] = {}
    with np.load(path, allow_pickle=False) as f:
        for key in f.files:
            c, k = key.split("/", 1)
            out.setdefault(c, {})[k] = f[key]
    return out


def pitch_augmentation_iou(shard_paths, size, geometry: dict) -> dict[str, float]:
    """Mean and minimum IoU, per pitch, between the pitch augmentation applied to the
    front-view (pitch 0) inputs and the inputs rendered at that pitch (masks at 1/2)."""
    import torch

    from ..dataset.pitch import pitch_silhouette

    arrays, table = load_test_set(shard_paths, size)
    pitch = table["pitch_deg"].to_numpy()
    front = arrays["images"][pitch == 0]
    x0 = torch.from_numpy(front[:, None].astype(np.float32) / 255.0)
    out = {}
    for p in sorted(set(pitch.tolist()) - {0.0}):
        true = arrays["images"][pitch == p] >= 128
        aug = (
            pitch_silhouette(
                x0,
                torch.full((len(x0),), float(p)),
                geometry["mm_per_px"],
                geometry["pitch_centre_row"],
                geometry["extrusion_mm"],
            )[:, 0].numpy()
            >= 0.5
        )
        iou = (aug & true).sum((1, 2)) / np.maximum((aug | true).sum((1, 2)), 1)
        iou0 = (front >= 128) & true
        out[f"{p:g}"] = {
            "iou_mean": float(iou.mean()),
            "iou_min": float(iou.min()),
            "iou_front_view_mean": float(
                (iou0.sum((1, 2)) / np.maximum(((front >= 128) | true).sum((1, 2)), 1)).mean()
            ),
        }
    return out


def fit_baseline(train_shards, size, out_npz, seed: int = 0) -> dict:
    """Fit the ridge baseline on the training shards; write it; return the CV record."""
    from .baseline import fit_ridge, front_edge_profile

    arrays, table = load_test_set(train_shards, size)
    feats = front_edge_profile(arrays["images"].astype(np.float32) / 255.0)
    model, info = fit_ridge(
        feats, table["fx_N"].to_numpy(), table["scene_id"].to_numpy(), seed=seed
    )
    model.save(out_npz)
    train_pred = model.predict(feats)
    info["train"] = force_metrics(table["fx_N"], train_pred)
    info["n_features"] = int(feats.shape[1])
    return info
