"""``results/summary.json``: the headline numbers of every experiment in one file, so
that a regression is one diff away; the manuscript's numbers all come from it."""
from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from .camera import PATH_KEYS
from .experiments import headline_rows, usable_range

#: The paper's own numbers (Frontiers in Robotics and AI 2021), for the comparison.
PAPER = {
    "shape_mse_N2_range": [0.02, 0.09],
    "material_mse_N2": {"steel": 0.02, "ninjaflex": 0.03, "neoprene": 0.02},
    "pitch_usable_below_deg": 10.0,
    "network_ms_per_frame_gpu": 8.0,
}
KEEP = ("n", "mse_N2", "rmse_N", "nrmse_pct", "r2", "max_true_N", "stress_mse_log", "ssim")


def _clean(d: dict) -> dict:
    return {k: (None if pd.isna(v) else v) for k, v in d.items() if k in KEEP}


def experiment_summary(exp_dir) -> dict:
    """``{condition: {predictor: {"all": metrics, "groups": {group: metrics}}}}`` of the
    shard path on all test frames; where the camera path ran (shape, material), each
    predictor also has ``"camera"`` (the rendered frames through the Predictor) and
    ``"shard_rendered"`` (the shard inputs of the same frames), each ``{"all", "groups"}``
    (see :data:`finray.evaluate.camera.PATH_KEYS`)."""
    m = pd.read_csv(Path(exp_dir) / "metrics.csv")
    out: dict = {}
    for r in m.to_dict("records"):
        node = out.setdefault(str(r["condition"]), {}).setdefault(r["predictor"], {"groups": {}})
        key = PATH_KEYS[(r.get("path", "shard"), r.get("frames", "all"))]
        if key is not None:
            node = node.setdefault(key, {"groups": {}})
        if r["group"] == "all":
            node["all"] = _clean(r)
        else:
            node["groups"][str(r["group"])] = _clean(r)
    return out


def camera_agreement(exp_dir) -> dict:
    """How far the camera path's forces are from the shard path's on the same frames
    (``frames.csv``): ``{condition: {predictor: {"n_frames", "max_abs_diff_N",
    "rms_diff_N"}}}``; empty where the camera path did not run."""
    f = pd.read_csv(Path(exp_dir) / "frames.csv")
    if "path" not in f or not (f["path"] == "camera").any():
        return {}
    key = [f.columns[0], "scene_id", "frame"]  # condition, scene, frame
    cam = f[f["path"] == "camera"]
    both = cam.merge(f[f["path"] == "shard"], on=key, suffixes=("_camera", "_shard"),
                     validate="one_to_one")
    out: dict = {}
    for c, g in both.groupby(key[0], sort=False):
        out[str(c)] = {}
        for p in (col[5:] for col in f.columns if col.startswith("pred_")):
            d = g[f"pred_{p}_camera"].to_numpy() - g[f"pred_{p}_shard"].to_numpy()
            out[str(c)][p] = {"n_frames": int(len(d)), "max_abs_diff_N": float(abs(d).max()),
                              "rms_diff_N": float((d ** 2).mean() ** 0.5)}
    return out


def setup_summary(cfg: dict) -> dict:
    """The set-up constants the manuscript quotes, from the config that ran."""
    f, fea = cfg["finger"], cfg["fea"]
    mat = cfg["materials"][f["material"]]
    return {"extrusion_mm": f["extrusion_mm"], "rib_angle_step_deg": f["ribs"]["angle_step_deg"],
            "n_ribs": f["ribs"]["count"], "finger_material": f["material"],
            "finger_E_MPa": mat.get("youngs_modulus_MPa"), "friction": fea["friction"],
            "push_mm": fea["push_mm"], "heights_mm": list(cfg["heights_mm"]),
            "mesh_size_mm": cfg["mesh"]["size_mm"], "input_size": list(cfg["train"]["input_size"]),
            "base_channels": cfg["train"]["base_channels"]}


def fea_checks(fea_scenes_csv) -> dict:
    """What the FEA scenes were checked against, over all scenes (``fea_scenes.csv``,
    one row per scene's ``summary.json``): the Newton residual tolerance and the
    largest residual reached (relative to the support forces), the per-frame
    equilibrium tolerance and the largest error (|force on object - clamp reaction|
    / |force|), the scene of each maximum, the summed line-search failures and
    gradient-descent fallbacks, and the smallest gap (mm). A scene failing a check
    stops the run, so the numbers describe scenes that passed."""
    df = pd.read_csv(fea_scenes_csv)

    def worst(col):
        i = df[col].idxmax()
        return float(df.at[i, col]), str(df.at[i, "scene"])

    res, res_scene = worst("residual_max_rel")
    eq, eq_scene = worst("equilibrium_max_rel_error")
    return {"n_scenes": int(len(df)),
            "residual_tol": float(df["residual_tol"].max()),
            "residual_max_rel": res, "residual_max_scene": res_scene,
            "equilibrium_tol": float(df["equilibrium_tol"].max()),
            "equilibrium_max_rel_error": eq, "equilibrium_max_scene": eq_scene,
            "line_search_failures": int(df["line_search_failures"].sum()),
            "gradient_fallbacks": int(df["gradient_fallbacks"].sum()),
            "min_gap_mm": float(df["min_gap_mm"].min())}


def build_summary(evaluate_dir, experiments, baseline_fit, speed_json, fea_pareto_csv,
                  histories: dict[str, str], usable_nrmse_pct: float, config: dict | None = None,
                  fea_scenes_csv=None) -> dict:
    evaluate_dir = Path(evaluate_dir)
    s: dict = {"experiments": {e: experiment_summary(evaluate_dir / e) for e in experiments}}
    s["camera_path"] = {e: a for e in experiments if (a := camera_agreement(evaluate_dir / e))}
    if config is not None:
        s["setup"] = setup_summary(config)
    if fea_scenes_csv is not None:
        s["fea_checks"] = fea_checks(fea_scenes_csv)
    if "pitch" in experiments:
        m = headline_rows(pd.read_csv(evaluate_dir / "pitch" / "metrics.csv"))
        s["pitch_usable_deg"] = {p: usable_range(m, p, usable_nrmse_pct)
                                 for p in m["predictor"].unique()}
        s["pitch_usable_nrmse_pct"] = usable_nrmse_pct
        allm = m[m["group"] == "all"]
        s["pitch_within_threshold_deg"] = {
            p: [float(c) for c in g.loc[g["nrmse_pct"] <= usable_nrmse_pct, "condition"]]
            for p, g in allm.groupby("predictor")}
        pitched = allm[allm["condition"].astype(float) > 0]
        s["pitch_nrmse_range_pct"] = {p: [float(g["nrmse_pct"].min()), float(g["nrmse_pct"].max())]
                                      for p, g in pitched.groupby("predictor")}
        checks = json.loads((evaluate_dir / "pitch" / "checks.json").read_text())
        s["pitch_augmentation_iou"] = checks.get("augmentation_iou", {})
    fit = json.loads(Path(baseline_fit).read_text())
    s["baseline"] = {"method": "ridge regression on the front-edge profile",
                     "alpha": fit["alpha"], "n_features": fit["n_features"],
                     "train_nrmse_pct": fit["train"]["nrmse_pct"]}
    s["training"] = {}
    for name, path in histories.items():
        h = json.loads(Path(path).read_text())
        s["training"][name] = {"augment": h.get("augment"),
                               "train_seconds": h["train_seconds"], "n_train": h["n_train"],
                               "n_val": h["n_val"], "epochs": len(h["epoch"]),
                               "precision": h.get("precision", ""), "step_ms": h.get("step_ms"),
                               "step_cpu_ms": h.get("step_cpu_ms"),
                               "cpu": h.get("cpu", ""),
                               "best_val_force_rmse_N": min(h["val_force_rmse_N"]) if h["val_force_rmse_N"] else None}
    speed = json.loads(Path(speed_json).read_text())
    s["fea_scenes"] = speed["fea_scenes"]
    s["speed"] = {"fea_seconds_per_scene": speed["fea_seconds_per_scene"],
                  "network_ms_per_frame": speed["network_ms_per_frame"],
                  "network_force_only_ms_per_frame": speed["network_force_only_ms_per_frame"],
                  "stages": speed["stages"]}
    pareto = pd.read_csv(fea_pareto_csv)
    s["fea_mesh_study"] = pareto.to_dict("records")
    s["paper"] = PAPER
    return s
