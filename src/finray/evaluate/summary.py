"""``results/summary.json``: the headline numbers of every experiment in one file, so
that a regression is one diff away; the manuscript's numbers all come from it."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from ..config import model_start
from ..paper_reference import paper_reference
from .tables import PATH_KEYS, headline_rows, usable_range

KEEP = (
    "n",
    "mse_N2",
    "rmse_N",
    "nrmse_pct",
    "r2",
    "max_true_N",
    "stress_mse_log",
    "ssim",
    *(
        f"{c}_{k}"
        for c in ("fy", "mag")
        for k in ("mse_N2", "rmse_N", "nrmse_pct", "r2", "max_true_N")
    ),
)


def _clean(d: dict) -> dict:
    return {k: (None if pd.isna(v) else v) for k, v in d.items() if k in KEEP}


def experiment_summary(exp_dir) -> dict:
    """``{condition: {predictor: {"all": metrics, "groups": {group: metrics}}}}`` of the
    shard path on all test frames; where the camera path ran (shape, material), each
    predictor also has ``"camera"`` (the rendered frames through the Predictor) and
    ``"shard_rendered"`` (the shard inputs of the same frames), each ``{"all", "groups"}``
    (see :data:`finray.evaluate.tables.PATH_KEYS`)."""
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
    "rms_diff_N"}}}``; empty where the camera path did not run, or ran alone."""
    f = pd.read_csv(Path(exp_dir) / "frames.csv")
    if "path" not in f or not (f["path"] == "camera").any() or not (f["path"] == "shard").any():
        return {}  # no camera path, or no shard path beside it (viewpoint)
    key = [f.columns[0], "scene_id", "frame"]  # condition, scene, frame
    cam = f[f["path"] == "camera"]
    both = cam.merge(
        f[f["path"] == "shard"], on=key, suffixes=("_camera", "_shard"), validate="one_to_one"
    )
    out: dict = {}
    for c, g in both.groupby(key[0], sort=False):
        out[str(c)] = {}
        for p in (
            col[5:]
            for col in f.columns
            if col.startswith("pred_") and not col.startswith("pred_fy_")
        ):
            d = g[f"pred_{p}_camera"].to_numpy() - g[f"pred_{p}_shard"].to_numpy()
            out[str(c)][p] = {
                "n_frames": int(len(d)),
                "max_abs_diff_N": float(abs(d).max()),
                "rms_diff_N": float((d**2).mean() ** 0.5),
            }
    return out


def setup_summary(cfg: dict) -> dict:
    """The set-up constants the manuscript quotes, from the config that ran."""
    f, fea = cfg["finger"], cfg["fea"]
    mat = cfg["materials"][f["material"]]
    return {
        "extrusion_mm": f["extrusion_mm"],
        "rib_angle_step_deg": f["ribs"]["angle_step_deg"],
        "n_ribs": f["ribs"]["count"],
        "finger_material": f["material"],
        "finger_E_MPa": mat.get("youngs_modulus_MPa"),
        "friction": fea["friction"],
        "push_mm": fea["push_mm"],
        "heights_mm": list(cfg["heights_mm"]),
        "mesh_size_mm": cfg["mesh"]["size_mm"],
        "input_size": list(cfg["train"]["input_size"]),
        "base_channels": cfg["train"]["base_channels"],
        "init": cfg["train"]["init"],
        "batch_size": cfg["train"]["batch_size"],
        "alpha_stress": cfg["train"]["alpha_stress"],
        "alpha_force": cfg["train"]["alpha_force"],
        "occlusion_levels": {k: list(v) for k, v in cfg["dataset"]["occlusion_levels"].items()},
        "viewpoint": cfg["evaluate"]["viewpoint"],
        "camera_views": cfg["render"]["camera_views"],
        # how each model trains: from another's weights, and its own epochs
        "epochs": cfg["train"]["epochs"],
        "model_start": {m: model_start(cfg, m) for m in sorted(cfg["train"]["models"])},
    }


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
    return {
        "n_scenes": int(len(df)),
        "residual_tol": float(df["residual_tol"].max()),
        "residual_max_rel": res,
        "residual_max_scene": res_scene,
        "equilibrium_tol": float(df["equilibrium_tol"].max()),
        "equilibrium_max_rel_error": eq,
        "equilibrium_max_scene": eq_scene,
        "line_search_failures": int(df["line_search_failures"].sum()),
        "gradient_fallbacks": int(df["gradient_fallbacks"].sum()),
        "min_gap_mm": float(df["min_gap_mm"].min()),
    }


def fea_forces(fea_scenes_csv, split: str = "train") -> dict:
    """How alike the scenes of ``split`` are, and how many jam: the largest coefficient
    of variation (std / mean, %) and spread ((max - min) / mean, %) of the final force
    across objects at one contact height, and the scenes whose finger touches itself
    (ribs on ribs or walls) with the first travel (mm) at which it does, min and max."""
    df = pd.read_csv(fea_scenes_csv)
    t = df[df["split"] == split]
    g = t.groupby("height_mm")["fx_final_N"]
    cv = (g.std(ddof=0) / g.mean()).max() * 100
    spread = ((g.max() - g.min()) / g.mean()).max() * 100
    touched = df[df["self_contact_max_pairs"].fillna(0) > 0]
    first = touched["self_contact_first_mm"].dropna()
    return {
        "split": split,
        "n_scenes": int(len(t)),
        "heights": int(g.ngroups),
        "force_cv_max_pct": float(cv),
        "force_spread_max_pct": float(spread),
        "self_contact_scenes": int(len(touched)),
        "n_scenes_all": int(len(df)),
        "self_contact_first_mm": [float(first.min()), float(first.max())] if len(first) else None,
    }


def training_data(manifest_csv, split: str = "train", pitch_deg: float = 0.0) -> dict:
    """The frames behind training (``split`` at ``pitch_deg``, from the dataset manifest)
    against the FEA states they come from: scenes, frames, solver frames (distinct FEA
    states: a scene's frames are resampled evenly in travel between its solver frames,
    ``fea_frame`` is the fractional solver-frame index, the last one exact) and the
    frames that fall exactly on a solver frame (the others are interpolated)."""
    m = pd.read_csv(manifest_csv)
    m = m[(m["split"] == split) & (m["pitch_deg"].astype(float) == pitch_deg)]
    last = m.groupby("scene_id")["fea_frame"].max()
    on = (m["fea_frame"] % 1 == 0).sum()
    return {
        "split": split,
        "pitch_deg": pitch_deg,
        "scenes": int(last.size),
        "frames": int(len(m)),
        "solver_frames": int((last.round() + 1).sum()),
        "solver_frames_per_scene": [int(last.min().round() + 1), int(last.max().round() + 1)],
        "frames_on_solver_frames": int(on),
    }


def training_summary(h: dict, manifest_csv=None) -> dict:
    """One model's ``history.json`` -> what the manuscript states: the epoch kept (as
    :func:`finray.train.train` kept it, ``train.keep``), its validation force RMSE, the
    learning-rate schedule and the batch-norm re-estimate,
    the force normalisation (mean and standard deviation of the training frames' force, N),
    the precision and the step time. A history written before ``best_epoch`` and the
    normalisation were recorded gets them by the same rules (the normalisation from the
    manifest's training frames less the validation scenes)."""
    score = h["val_loss"] or h["train_loss"]
    best = h.get("best_epoch") or (
        h["epoch"][min(range(len(score)), key=score.__getitem__)] if score else None
    )
    # a history written before the schedule was configurable: the paper's constant rate,
    # the epoch kept by validation loss, training's running batch-norm averages
    tc = h.get("train_config") or {}
    keep = tc.get("keep", "val_loss")
    k = h["epoch"].index(best) if best in h["epoch"] else None
    val_rmse = h["val_force_rmse_N"][k] if k is not None and h["val_force_rmse_N"] else None
    mean, std = h.get("force_mean_N") or None, h.get("force_std_N") or None
    if mean is None and manifest_csv is not None:
        m = pd.read_csv(manifest_csv)
        f = m.loc[
            (m["split"] == "train")
            & (m["pitch_deg"].astype(float) == 0.0)
            & ~m["scene_id"].isin(h.get("validation_scenes", [])),
            "fx_N",
        ]
        mean, std = [float(f.mean())], [float(f.std(ddof=1))]  # torch.std: unbiased
    return {
        "augment": h.get("augment"),
        "train_seconds": h["train_seconds"],
        "n_train": h["n_train"],
        "n_val": h["n_val"],
        "n_val_scenes": len(h.get("validation_scenes", [])),
        "epochs": len(h["epoch"]),
        "best_epoch": best,
        "selected_by": (
            "training loss"
            if not h["val_loss"]
            else {
                "val_force_rmse": "validation force RMSE",
                "val_loss": "validation loss",
                "last": "last epoch",
            }[keep]
        ),
        "lr": tc.get("lr"),
        "schedule": tc.get("schedule", "constant"),
        "warmup_frac": tc.get("warmup_frac", 0.0),
        "bn_frames": tc.get("bn_frames", 0),
        "ema_decay": tc.get("ema_decay", 0.0),  # > 0: the kept weights are their moving average
        "frame_every": h.get("frame_every", 1),  # every k-th rendered frame of a scene
        "best_val_force_rmse_N": val_rmse,
        "force_mean_N": mean,
        "force_std_N": std,
        "precision": h.get("precision", ""),
        "step_ms": h.get("step_ms"),
        "step_cpu_ms": h.get("step_cpu_ms"),
        "cpu": h.get("cpu", ""),
    }


def viewpoint_summary(exp_dir, usable_nrmse_pct: float) -> dict:
    """The viewpoint experiment (perspective renders through the predictor): per
    predictor, the largest pitch up to which the force NRMSE (%) stays within the
    threshold (over all distances, and per distance; None: not even 0 deg), the NRMSE at
    every pitch (all frames, per distance) and that of fy; the distances (mm) and the
    frames per pitch."""
    m = headline_rows(pd.read_csv(Path(exp_dir) / "metrics.csv"))
    m = m.assign(group=m["group"].astype(str))
    groups = [g for g in dict.fromkeys(m["group"]) if g != "all"]

    def usable(df, p):
        return usable_range(df.assign(group="all"), p, usable_nrmse_pct)

    first = m[m["group"] == "all"].iloc[0]
    out = {
        "threshold_pct": usable_nrmse_pct,
        "n_frames_per_pitch": int(first["n"]),
        "distances_mm": [float(g) for g in groups],
        "usable_deg": {},
        "usable_deg_by_distance": {},
        "nrmse_pct": {},
        "nrmse_pct_by_distance": {},
        "fy_nrmse_pct": {},
    }
    for p, g in m.groupby("predictor", sort=False):
        allg = g[g["group"] == "all"]
        out["usable_deg"][p] = usable(allg, p)
        out["nrmse_pct"][p] = {
            f"{float(c):g}": float(v) for c, v in zip(allg["condition"], allg["nrmse_pct"])
        }
        if "fy_nrmse_pct" in allg and allg["fy_nrmse_pct"].notna().all():
            out["fy_nrmse_pct"][p] = {
                f"{float(c):g}": float(v) for c, v in zip(allg["condition"], allg["fy_nrmse_pct"])
            }
        out["usable_deg_by_distance"][p] = {d: usable(g[g["group"] == d], p) for d in groups}
        out["nrmse_pct_by_distance"][p] = {
            d: {
                f"{float(c):g}": float(v)
                for c, v in zip(
                    g.loc[g["group"] == d, "condition"], g.loc[g["group"] == d, "nrmse_pct"]
                )
            }
            for d in groups
        }
    return out


#: What the summary keeps of a ``heights.csv`` row.
HEIGHT_KEEP = ("height_mm", "band_mm", "unseen", "n", "rmse_N", "nrmse_pct", "max_true_N")


def face_summary(exp_dir, condition: str = "all") -> dict | None:
    """Contacts over the finger's face in one experiment's condition (shard path): per
    predictor, the force metrics at each test height (``heights.csv``: RMSE in N, NRMSE
    in % of that height's largest |Fx|) and over the frames at heights no training scene
    used (``unseen``) and at the others (``seen``), from ``frames.csv``; with a contact
    head, the contact height's RMSE (mm) on the frames with |Fx| above
    ``CONTACT_MIN_FORCE_N`` too. None where every test height is a training height (no
    face heights)."""
    from .metrics import CONTACT_MIN_FORCE_N, contact_metrics, force_metrics

    h = pd.read_csv(Path(exp_dir) / "heights.csv")
    h = h[h["condition"].astype(str) == condition]
    if h.empty or not h["unseen"].any():
        return None
    f = pd.read_csv(Path(exp_dir) / "frames.csv")
    f = f[(f["path"] == "shard") & (f.iloc[:, 0].astype(str) == condition)]
    unseen = sorted({float(x) for x in h.loc[h["unseen"], "height_mm"]})
    is_unseen = f["height_mm"].astype(float).isin(unseen).to_numpy()
    out = {
        "heights_mm": sorted({float(x) for x in h["height_mm"]}),
        "unseen_heights_mm": unseen,
        "by_height": {},
        "unseen": {},
        "seen": {},
    }
    for p, g in h.groupby("predictor", sort=False):
        keep = HEIGHT_KEEP + (
            ("contact_rmse_mm",)
            if "contact_rmse_mm" in g and g["contact_rmse_mm"].notna().any()
            else ()
        )
        out["by_height"][p] = [
            {k: (bool(r[k]) if k == "unseen" else float(r[k])) for k in keep}
            for r in g.sort_values("height_mm").to_dict("records")
        ]
        for key, sel in (("unseen", is_unseen), ("seen", ~is_unseen)):
            if sel.any():
                m = force_metrics(f["fx_N"][sel], f[f"pred_{p}"][sel])
                out[key][p] = {k: m[k] for k in ("n", "rmse_N", "nrmse_pct", "max_true_N")}
                if f"contact_pred_{p}" in f and "contact_y_mm" in f:
                    c = contact_metrics(
                        f["contact_y_mm"][sel],
                        f[f"contact_pred_{p}"][sel],
                        f["fx_N"][sel],
                        CONTACT_MIN_FORCE_N,
                    )
                    out[key][p] |= {"contact_rmse_mm": c["rmse_mm"], "contact_n": c["n"]}
    return out


def lab_summary(qa_json, qa_csv, lab_setup: dict) -> dict:
    """The emulated lab takes (:mod:`finray.evaluate.lab_takes`): the QA over all takes,
    one record per take, and the emulator's set-up (``lab`` config, less the scene)."""
    return {
        "emulated": True,
        "qa": json.loads(Path(qa_json).read_text()),
        "takes": pd.read_csv(qa_csv).to_dict("records"),
        "setup": lab_setup,
    }


def build_summary(
    evaluate_dir,
    experiments,
    baseline_fit,
    speed_json,
    fea_pareto_csv,
    histories: dict[str, str],
    usable_nrmse_pct: float,
    config: dict | None = None,
    fea_scenes_csv=None,
    manifest_csv=None,
) -> dict:
    evaluate_dir = Path(evaluate_dir)
    s: dict = {"experiments": {e: experiment_summary(evaluate_dir / e) for e in experiments}}
    s["camera_path"] = {e: a for e in experiments if (a := camera_agreement(evaluate_dir / e))}
    if config is not None:
        s["setup"] = setup_summary(config)
    if fea_scenes_csv is not None:
        s["fea_checks"] = fea_checks(fea_scenes_csv)
        s["fea_forces"] = fea_forces(fea_scenes_csv)
    if manifest_csv is not None:
        s["training_data"] = training_data(manifest_csv)
    if "pitch" in experiments:
        m = headline_rows(pd.read_csv(evaluate_dir / "pitch" / "metrics.csv"))
        s["pitch_usable_deg"] = {
            p: usable_range(m, p, usable_nrmse_pct) for p in m["predictor"].unique()
        }
        s["pitch_usable_nrmse_pct"] = usable_nrmse_pct
        allm = m[m["group"] == "all"]
        s["pitch_within_threshold_deg"] = {
            p: [float(c) for c in g.loc[g["nrmse_pct"] <= usable_nrmse_pct, "condition"]]
            for p, g in allm.groupby("predictor")
        }
        pitched = allm[allm["condition"].astype(float) > 0]
        s["pitch_nrmse_range_pct"] = {
            p: [float(g["nrmse_pct"].min()), float(g["nrmse_pct"].max())]
            for p, g in pitched.groupby("predictor")
        }
        checks = json.loads((evaluate_dir / "pitch" / "checks.json").read_text())
        s["pitch_augmentation_iou"] = checks.get("augmentation_iou", {})
    if "viewpoint" in experiments:
        s["viewpoint"] = viewpoint_summary(evaluate_dir / "viewpoint", usable_nrmse_pct)
    if "shape" in experiments and (face := face_summary(evaluate_dir / "shape")) is not None:
        s["face"] = {"shape": face}
    for e in ("shape", "material"):  # the camera model on front views, against the plain one
        node = s["experiments"].get(e, {}).get("all", {})
        if "camera" in node and "plain" in node:
            s.setdefault("camera_model", {})[e] = {
                "plain_nrmse_pct": node["plain"]["all"]["nrmse_pct"],
                "camera_nrmse_pct": node["camera"]["all"]["nrmse_pct"],
                "loss_pp": node["camera"]["all"]["nrmse_pct"] - node["plain"]["all"]["nrmse_pct"],
            }
    fit = json.loads(Path(baseline_fit).read_text())
    s["baseline"] = {
        "method": "ridge regression on the front-edge profile",
        "alpha": fit["alpha"],
        "n_features": fit["n_features"],
        "train_nrmse_pct": fit["train"]["nrmse_pct"],
    }
    s["training"] = {}
    for name, path in histories.items():
        s["training"][name] = training_summary(json.loads(Path(path).read_text()), manifest_csv)
    speed = json.loads(Path(speed_json).read_text())
    s["fea_scenes"] = speed["fea_scenes"]
    s["speed"] = {
        "fea_seconds_per_scene": speed["fea_seconds_per_scene"],
        "network_ms_per_frame": speed["network_ms_per_frame"],
        "network_force_only_ms_per_frame": speed["network_force_only_ms_per_frame"],
        "stages": speed["stages"],
        "studies": speed["studies"],
        "dag": speed["dag"],
    }
    if fea_pareto_csv is not None:  # the FEA cost study (studies/fea_cost), where it was built
        s["fea_mesh_study"] = pd.read_csv(fea_pareto_csv).to_dict("records")
    s["paper"] = paper_reference()["values"]  # {name: {value, unit, where, quote}}
    return s


#: Nodes that come from a study (studies/<name>/), present only where that study was
#: built before the summary: the default run builds none (``fea_mesh_study``: the FEA
#: cost study's table, ``snakemake --cores 2 fea_cost``).
STUDY_NODES = ("fea_mesh_study",)


#: Where the summary's keys are names from the config or the data (conditions, groups,
#: materials, stages, pitches, the models that train.models lists) rather than fixed
#: keys: see :func:`key_structure`.
NAMED = [
    ("experiments", "*"),
    ("experiments", "*", "*"),
    ("experiments", "*", "*", "*", "groups"),
    ("camera_path", "*", "*"),
    ("pitch_usable_deg",),
    ("pitch_within_threshold_deg",),
    ("pitch_nrmse_range_pct",),
    ("viewpoint", "usable_deg"),
    ("viewpoint", "usable_deg_by_distance"),
    ("viewpoint", "nrmse_pct"),
    ("viewpoint", "nrmse_pct_by_distance"),
    ("viewpoint", "fy_nrmse_pct"),
    ("experiments", "*", "*", "*", "*", "groups"),  # camera / shard_rendered groups
    ("speed", "fea_seconds_per_scene"),
    ("speed", "stages"),
    ("speed", "studies"),
    ("pitch_augmentation_iou",),
    ("viewpoint", "usable_deg_by_distance", "*"),
    ("viewpoint", "nrmse_pct", "*"),
    ("viewpoint", "nrmse_pct_by_distance", "*"),
    ("viewpoint", "nrmse_pct_by_distance", "*", "*"),
    ("viewpoint", "fy_nrmse_pct", "*"),
    ("setup", "occlusion_levels"),
    ("sim2real", "by_context"),
    ("sim2real", "by_context", "*", "per_object"),
    ("sim2real_rigs", "by_context"),
    ("sim2real_rigs", "per_rig"),
    ("sim2real_rigs", "settings"),
    ("diversity", "tests", "*", "groups"),
    ("training",),
    ("setup", "model_start"),  # the models train.models lists
    ("face", "shape", "by_height"),
    ("face", "shape", "unseen"),
    ("face", "shape", "seen"),
    ("sim2real", "by_context", "*", "per_height"),
    ("sim2real_rigs", "per_height"),
    ("sim2real_rigs", "per_height", "*"),
    ("sim2real_rigs", "per_height", "*", "*"),
    # the phases of the takes (a config's takes may lack one) and the rigs' own
    ("sim2real", "by_context", "*", "per_phase"),
    ("sim2real", "by_context", "*", "per_phase_face"),
    ("sim2real_rigs", "phases", "by_context"),
    ("sim2real_rigs", "phases", "by_context", "*"),
    ("sim2real_rigs", "phases", "per_rig"),
    ("sim2real_rigs", "phases", "per_rig", "*"),
    ("sim2real_rigs", "phases", "per_rig", "*", "*"),
]


def key_structure(node, path: tuple = ()):
    """The shape of a summary: nested dicts of its keys, with the names listed in
    :data:`NAMED` merged under ``"*"``, a list of records as ``["[]", keys]`` and
    values as ``None``; two runs of different configs compare equal when only those
    names differ."""

    def match(p):
        return any(
            len(p) == len(n) and all(a == b or b == "*" for a, b in zip(p, n)) for n in NAMED
        )

    if isinstance(node, dict):
        if match(path):
            merged: dict = {}
            for k, v in node.items():
                merged = _union(merged, key_structure(v, path + (k,)))
            return {"*": merged} if node else {}
        return {k: key_structure(v, path + (k,)) for k, v in node.items()}
    if isinstance(node, list) and node and all(isinstance(v, dict) for v in node):
        merged = {}
        for v in node:
            merged = _union(merged, key_structure(v, path + ("[]",)))
        return ["[]", merged]
    return None


def _union(a, b):
    if isinstance(a, dict) and isinstance(b, dict):
        return {
            k: _union(a.get(k), b.get(k)) if k in a and k in b else (a.get(k) if k in a else b[k])
            for k in {**a, **b}
        }
    return a if a is not None else b
