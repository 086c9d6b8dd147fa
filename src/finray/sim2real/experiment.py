"""Sim-to-real with context objects (the paper's section 5.3) and the calibrated force.

The simulation-trained network meets the lab takes (ingested shards, sensor labels)
with 0, 1 or 2 of their objects as *context*: the rig's head ensemble
(:mod:`finray.sim2real.adapt`) is fitted on the context objects' frames at every height, the
sensor calibration (:mod:`finray.sim2real.calibration`) on the same frames' cross-fitted
predictions, and both are tested on the remaining objects at every height. Every
leave-out combination is run. With no context, the force is the model's own head,
what ``finray predict`` reads uncalibrated from the same frame, and the rest comes from
the simulation alone: the spread of heads fitted again on the training frames, and the
calibration on predictions of training objects by heads fitted without them; the same
calibration is checked on the simulated test frames (the held-out shapes). With a single object in
the takes (a short check), its takes' first and second halves stand in for objects.

Metrics are against the sensor (the label a rig gives: its gain error and offset
included), of the posterior predictive median, and the share of frames inside the
``level`` predictive interval.
"""

from __future__ import annotations

import itertools
import json
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

from .adapt import HeadFit, SimAnchor, encoder_features, head_forces, head_from_state
from .calibration import (
    History,
    Priors,
    RigPrior,
    Sampler,
    coverage,
    fit_rig,
    fold_units,
    predictive,
    shard_times,
    spread,
)
from ..paper_reference import paper_value
from ..schema import schema_default
from ..evaluate.metrics import force_metrics


def paper_mse_N2() -> dict[int, float]:
    """The paper's MSE (N^2) with 0, 1 and 2 context objects (section 5.3)."""
    v = paper_value("sim_to_real_mse_N2")
    return {0: v["sim_only"], 1: v["one_real_sample"], 2: v["two_real_samples"]}


@dataclass(frozen=True)
class Sim2RealConfig:
    heads: HeadFit = field(default_factory=HeadFit)
    folds: str = schema_default("evaluate.sim2real.folds")
    level: float = schema_default("evaluate.sim2real.level")
    max_context: int = schema_default("evaluate.sim2real.max_context")
    sim_every: int = schema_default("evaluate.sim2real.sim_every")
    sim_folds: int = schema_default("evaluate.sim2real.sim_folds")
    # the simulated frames of the no-context fit (SIM_VIEWS)
    sim_views: str = schema_default("evaluate.sim2real.sim_views")
    # simulated frames fitted beside each fit's context frames (SimAnchor)
    sim_replay_frames: int = schema_default("evaluate.sim2real.sim_replay_frames")
    # the phases' figures apart for the takes from this height (mm): the face a print covers
    phase_min_height_mm: float = schema_default("evaluate.sim2real.phase_min_height_mm")
    priors: Priors = field(default_factory=Priors)
    sampler: Sampler = field(default_factory=Sampler)
    rig_prior: RigPrior = field(default_factory=RigPrior)  # with no context frames

    @classmethod
    def from_params(cls, p: dict) -> "Sim2RealConfig":
        pr = p.get("priors", {})
        return cls(
            heads=HeadFit(**p.get("heads", {})),
            folds=str(p.get("folds", cls.folds)),
            level=float(p.get("level", cls.level)),
            max_context=int(p.get("max_context", cls.max_context)),
            sim_every=int(p.get("sim_every", cls.sim_every)),
            sim_folds=int(p.get("sim_folds", cls.sim_folds)),
            sim_views=str(p.get("sim_views", cls.sim_views)),
            sim_replay_frames=int(p.get("sim_replay_frames", cls.sim_replay_frames)),
            phase_min_height_mm=float(p.get("phase_min_height_mm", cls.phase_min_height_mm)),
            priors=Priors(**{k: tuple(v) if isinstance(v, list) else v for k, v in pr.items()}),
            sampler=Sampler(**p.get("sampler", {})),
            rig_prior=RigPrior(**{k: v for k, v in p.get("rig_prior", {}).items() if k != "gain"}),
        )

    def with_rig_prior(self, path) -> "Sim2RealConfig":
        """This config with the rig prior's gain of a ``rig_prior.json``
        (:mod:`finray.sim2real.rig_prior`)."""
        prior = json.loads(Path(path).read_text())
        return replace(
            self,
            rig_prior=replace(
                self.rig_prior,
                gain_log_mean=float(prior["gain_log_mean"]),
                gain_log_sd=float(prior["gain_log_sd"]),
            ),
        )


#: Which simulated views the no-context heads are fitted on: the front view,
#: each frame's randomised camera view (what a rig's camera sees), or both.
SIM_VIEWS = ("front", "camera", "both")

#: Simulated frames whose features the no-context file keeps for the context fits
#: (:class:`finray.sim2real.adapt.SimAnchor`, ``sim_replay_frames`` drawn for each fit), drawn
#: from those of the no-context fit; float16, 8 MB.
ANCHOR_FRAMES = 4096


def _frames(shards, size, every=1, views="front"):
    """Network inputs (N, 1, H, W) float32, fx_N, and the frame table of shards;
    ``views`` (:data:`SIM_VIEWS`): ``both`` stacks the camera views after the front views."""
    from ..dataset import load_frames

    if views not in SIM_VIEWS:
        raise ValueError(f"evaluate.sim2real.sim_views: {views!r} is not one of {list(SIM_VIEWS)}")
    try:
        a, table = load_frames(shards, tuple(size), every, camera=views != "front")
    except ValueError as e:
        if views == "front":
            raise
        raise ValueError(
            f"evaluate.sim2real.sim_views: {views} reads the camera views, and {e}; "
            "set sim_views: front"
        ) from None
    x, y = a["images"], a["fx_N"]
    if views == "camera":
        x = a["camera_images"]
    elif views == "both":
        x, y = np.concatenate([x, a["camera_images"]]), np.tile(y, 2)
        table = pd.concat([table, table], ignore_index=True)
    return x[:, None].astype(np.float32) / np.float32(255.0), y, table


def lab_table(shards, table: pd.DataFrame) -> pd.DataFrame:
    """The lab frames' table with their camera time (s, ``t_s``), take (``take``) and
    group (the object; with a single object, the take's first or second half)."""
    table = table.assign(t_s=shard_times(shards), take=table["scene_id"].to_numpy())
    if table["object"].nunique() >= 2:
        return table.assign(group=table["object"])
    late = table.groupby("take")["t_s"].transform(lambda s: s > s.median())
    return table.assign(group=table["object"] + np.where(late, " (2nd half)", " (1st half)"))


def object_folds(objects, n: int) -> np.ndarray:
    """A fold label per frame: the objects, sorted, dealt into ``n`` folds in turn."""
    names = sorted(set(np.asarray(objects).tolist()))
    fold = {o: f"fold {i % n}" for i, o in enumerate(names)}
    return np.array([fold[o] for o in objects])


def own_forces(model, features) -> np.ndarray:
    """The model's own force head along the push (N) on encoder features (N, F): what
    ``finray predict`` gives without calibration."""
    return head_forces(model, [model.force_head], features)[0]


def fit_no_context(
    model_pt, sim_shards, sim_test_shards, size, cfg: Sim2RealConfig, log=print
) -> dict:
    """The no-context heads and calibration, from the simulation alone and so the same for
    every rig: heads on the training frames (every ``cfg.sim_every``-th), calibrated on
    predictions of training objects by heads fitted without them (``cfg.sim_folds``
    folds, as a test object is new to them), checked on the simulated test frames.
    Returns ``{"heads": [state dicts], "calibration", "simulated_test", "anchor"}``
    (:func:`save_no_context`; ``anchor``: :data:`ANCHOR_FRAMES` of the simulated frames'
    features and forces, for :meth:`finray.sim2real.adapt.SimAnchor.from_file`)."""
    import torch

    from ..train import load_checkpoint

    t0 = time.perf_counter()
    model, _ = load_checkpoint(model_pt)
    xs, ys, ts = _frames(sim_shards, size, cfg.sim_every, cfg.sim_views)
    f_sim = encoder_features(model, xs)
    # the held-out shapes have no camera views (rendered for training scenes only)
    xt, yt, _ = _frames(sim_test_shards, size, cfg.sim_every)
    f_test = encoder_features(model, xt)
    log(
        f"features: {len(xs)} simulated, {len(xt)} simulated test frames ({time.perf_counter() - t0:.1f} s)"
    )
    heads0, cal0 = fit_rig(
        model,
        f_sim,
        ys,
        [object_folds(ts["object"].to_numpy(), cfg.sim_folds)],
        cfg.heads,
        cfg.priors,
        cfg.sampler,
        log=log,
    )
    cal0.update(
        context_objects=0,
        context="none",
        fitted_on="simulated training frames, objects cross-fitted",
    )
    p_test = head_forces(model, heads0, f_test)
    own = own_forces(model, f_test)
    sim_band = predictive(cal0, own, spread(p_test), cfg.level)
    sim = {
        "n_frames": int(len(yt)),
        "coverage_pct": 100 * coverage(yt, sim_band),
        "metrics": force_metrics(yt, sim_band["median"]),
        "raw_metrics": force_metrics(yt, own),
        "own_head": force_metrics(yt, own),
        "heads_mean": force_metrics(yt, p_test.mean(0)),  # the refitted heads', for comparison
        "shards": len(sim_test_shards),
        "every": cfg.sim_every,
        "views": "front",
        "heads_fitted_on": cfg.sim_views,
    }
    log(
        f"no context: {time.perf_counter() - t0:.1f} s; simulated test frames inside the "
        f"{cfg.level:.0%} interval: {sim['coverage_pct']:.1f} %"
    )
    pick = np.sort(
        np.random.default_rng(cfg.heads.seed).choice(
            len(ys), min(ANCHOR_FRAMES, len(ys)), replace=False
        )
    )
    anchor = {
        "features": f_sim[pick].half(),
        "force_N": torch.tensor(ys[pick], dtype=torch.float32),
    }
    return {
        "heads": [h.state_dict() for h in heads0],
        "calibration": cal0,
        "simulated_test": sim,
        "anchor": anchor,
    }


def save_no_context(result: dict, path) -> None:
    """:func:`fit_no_context`'s result as one file: the heads' weights and the rest as JSON."""
    import torch

    torch.save(
        {
            "heads": result["heads"],
            "anchor": result["anchor"],
            "info": json.dumps({k: result[k] for k in ("calibration", "simulated_test")}),
        },
        path,
    )


def load_no_context(model, path) -> tuple[list, dict, dict]:
    """The no-context heads on ``model`` (as :func:`finray.sim2real.adapt.fit_heads` returns them),
    their calibration and the simulated test's check, from :func:`save_no_context`'s file."""
    from ..train.export import load_plain

    saved = load_plain(path, "a no-context fit (no_context.pt)")
    info = json.loads(saved["info"])
    return (
        [head_from_state(model, state) for state in saved["heads"]],
        info["calibration"],
        info["simulated_test"],
    )


def lab_near_base(model, features, own_N, meta: dict | None) -> tuple[np.ndarray, np.ndarray]:
    """The contact head's height (mm; NaN without that head) of frames with encoder
    ``features`` and which of them ``finray predict`` flags ``near_base``
    (:func:`finray.validity.near_base`; ``meta``: the exported model's ``model.ts.json``,
    None: none flagged), the frame's force ``own_N`` (N) the model's own head's."""
    import torch

    from ..validity import near_base

    n = len(own_N)
    if not model.cfg.contact:
        return np.full(n, np.nan), np.zeros(n, bool)
    with torch.inference_mode():
        c = model.contact_of_latent(features).numpy().astype(np.float64) if n else np.zeros(0)
    meta = meta or {}
    return c, near_base(c, own_N, meta.get("trained"), meta.get("contact_min_force_N", 0.0))


def run_sim2real(
    model_pt, lab_shards, no_context, size, cfg: Sim2RealConfig, log=print, meta=None, phases=None
) -> dict:
    """Every context combination; ``no_context``: :func:`save_no_context`'s file of the
    same model; ``meta``: the exported model's ``model.ts.json`` (a dict), whose training
    ranges flag frames ``near_base`` as ``finray predict`` does: the test reports every
    frame and the frames not flagged apart. Returns ``{"metrics", "frames"}`` (DataFrames), ``"calibrations"``
    (one per fit) and ``"summary"``."""
    from ..train import load_checkpoint

    t0, c0 = time.perf_counter(), time.process_time()
    model, _ = load_checkpoint(model_pt)
    x, y, table = _frames(lab_shards, size)
    table = lab_table(lab_shards, table)
    f_lab = encoder_features(model, x)
    log(f"features: {len(x)} lab frames ({time.perf_counter() - t0:.1f} s)")

    groups = sorted(table["group"].unique())
    frames, cals = [], []

    own = own_forces(model, f_lab)
    contact, flagged = lab_near_base(model, f_lab, own, meta)
    log(f"near_base: {int(flagged.sum())} of {len(flagged)} lab frames flagged")

    def record(k, context, test, heads, cal):
        mu_all = head_forces(model, heads, f_lab[test])
        # no context: the model's own force (finray predict's), the refitted heads' spread
        mu, sd = (mu_all.mean(0) if k else own[test]), spread(mu_all)
        # no context: the rig's gain and offset are unknown (cfg.rig_prior)
        tab = table[test]
        # the print's law over each test take's frames (a time-dependent calibration)
        hist = History(tab["t_s"].to_numpy(), tab["take"].to_numpy())
        band = predictive(cal, mu, sd, cfg.level, rig=None if k else cfg.rig_prior, history=hist)
        frames.append(
            pd.DataFrame(
                {
                    "context_objects": k,
                    "context": " + ".join(context) or "none",
                    "take": tab["take"].to_numpy(),
                    "group": tab["group"].to_numpy(),
                    "height_mm": tab["height_mm"].to_numpy(dtype=float),
                    "frame": tab["frame"].to_numpy(),
                    "t_s": tab["t_s"].to_numpy(),
                    "sensor_N": y[test],
                    "net_mean_N": mu,
                    "net_spread_N": sd,
                    "own_head_N": own[test],
                    "contact_mm": contact[test],
                    "near_base": flagged[test],
                    "pred_N": band["median"],
                    "lo_N": band["lo"],
                    "hi_N": band["hi"],
                    "phase": "all" if phases is None else phases[test],
                }
            )
        )

    # no context: the simulation's heads and calibration (fit_no_context), the rig prior on top
    heads0, cal0, sim = load_no_context(model, no_context)
    anchor = SimAnchor.from_file(model, no_context, cfg.sim_replay_frames)
    cal0.update(rig_prior=asdict(cfg.rig_prior))
    cals.append(cal0)
    record(0, (), np.ones(len(y), bool), heads0, cal0)

    for k in range(1, min(cfg.max_context, len(groups) - 1) + 1):
        for context in itertools.combinations(groups, k):
            t1 = time.perf_counter()
            ctx = table["group"].isin(context).to_numpy().copy()
            # the frames flagged near_base stay in the fit: left out, the error on the
            # other frames and the coverage got worse on 3 of 4 emulated rigs
            # (docs/studies/face.md, "Sim-to-real near the base")
            fit = replace(cfg.heads, seed=cfg.heads.seed + 7 * len(cals))
            heads, cal = fit_rig(
                model,
                f_lab[ctx],
                y[ctx],
                fold_units(table[ctx], cfg.folds),
                fit,
                cfg.priors,
                cfg.sampler,
                log=log,
                anchor=anchor,
                history=History(table["t_s"].to_numpy()[ctx], table["take"].to_numpy()[ctx]),
            )
            cal.update(
                context_objects=k,
                context=" + ".join(context),
                fitted_on="context takes",
                near_base_frames=int((ctx & flagged).sum()),
            )
            cals.append(cal)
            record(k, context, ~ctx, heads, cal)
            log(f"context {' + '.join(context)}: {time.perf_counter() - t1:.1f} s")

    frames = pd.concat(frames, ignore_index=True)
    metrics = metrics_table(frames, cfg.level, cfg.phase_min_height_mm)
    summary = summarise_runs(metrics, cals, sim, cfg)
    summary["wall_s"], summary["cpu_s"] = time.perf_counter() - t0, time.process_time() - c0
    return {"metrics": metrics, "frames": frames, "calibrations": cals, "summary": summary}


def _row(g: pd.DataFrame) -> dict:
    m = force_metrics(g["sensor_N"], g["pred_N"])
    raw = force_metrics(g["sensor_N"], g["net_mean_N"])
    inside = (g["sensor_N"] >= g["lo_N"]) & (g["sensor_N"] <= g["hi_N"])
    return {
        "n": m["n"],
        "mse_N2": m["mse_N2"],
        "rmse_N": m["rmse_N"],
        "nrmse_pct": m["nrmse_pct"],
        "max_sensor_N": m["max_true_N"],
        "coverage_pct": float(100 * inside.mean()),
        "raw_mse_N2": raw["mse_N2"],
        "raw_nrmse_pct": raw["nrmse_pct"],
        "n_near_base": int(g["near_base"].sum()) if "near_base" in g else 0,
    }


def metrics_table(frames: pd.DataFrame, level: float, min_height_mm: float = 0.0) -> pd.DataFrame:
    """Per context size: every (context, test object) pair, each test object over its
    contexts, all frames (``test`` ``all``), the frames not flagged ``near_base``
    (``context`` ``unflagged``, ``test`` ``all``), each contact height over its
    contexts (``context`` ``by_height``, ``test`` the height in mm) and each phase of
    the takes (``context`` ``by_phase``, and ``by_phase_face`` of the takes at
    ``min_height_mm`` or higher; ``test`` the phase; NRMSE in % of the largest force of
    all those frames, every phase's); the paper's MSE beside."""
    rows = []
    for k, gk in frames.groupby("context_objects"):
        for (ctx, grp), g in gk.groupby(["context", "group"]):
            rows.append({"context_objects": k, "context": ctx, "test": grp, **_row(g)})
        for grp, g in gk.groupby("group"):
            rows.append({"context_objects": k, "context": "all", "test": grp, **_row(g)})
        rows.append({"context_objects": k, "context": "all", "test": "all", **_row(gk)})
        ok = gk[~gk["near_base"]] if "near_base" in gk else gk
        if len(ok):
            rows.append({"context_objects": k, "context": "unflagged", "test": "all", **_row(ok)})
        if "phase" in gk and (gk["phase"] != "all").any():
            face = gk[gk["height_mm"] >= min_height_mm]
            for name, sub in (("by_phase", gk), ("by_phase_face", face)):
                # in % of the largest force of every phase's frames: a phase's error
                # on the scale of the takes' force (the rest's own largest is ~0)
                top = float(np.max(np.abs(sub["sensor_N"]))) if len(sub) else np.nan
                for ph, g in sub.groupby("phase"):
                    row = _row(g)
                    row["nrmse_pct"] = 100 * row["rmse_N"] / top
                    row["raw_nrmse_pct"] = 100 * np.sqrt(row["raw_mse_N2"]) / top
                    rows.append({"context_objects": k, "context": name, "test": ph, **row})
        if "height_mm" in gk:  # each contact height over its contexts (context "by_height")
            for h, g in gk.groupby("height_mm"):
                rows.append(
                    {
                        "context_objects": k,
                        "context": "by_height",
                        "test": f"{float(h):g}",
                        **_row(g),
                    }
                )
    out = pd.DataFrame(rows)
    out["paper_mse_N2"] = out["context_objects"].map(paper_mse_N2())
    out["interval"] = f"{level:.0%}"
    return out


def summarise_runs(metrics: pd.DataFrame, cals: list[dict], sim: dict, cfg: Sim2RealConfig) -> dict:
    """The summary's ``sim2real``: per context size the overall and per-object metrics,
    the paper's MSE, coverage, and every fit's posterior and diagnostics."""
    by_k = {}
    for k, g in metrics[metrics["context"] == "all"].groupby("context_objects"):
        tot = g[g["test"] == "all"].iloc[0]
        by_k[str(int(k))] = {
            **{
                c: float(tot[c])
                for c in (
                    "mse_N2",
                    "rmse_N",
                    "nrmse_pct",
                    "coverage_pct",
                    "raw_mse_N2",
                    "raw_nrmse_pct",
                    "max_sensor_N",
                )
            },
            "n_frames": int(tot["n"]),
            "n_near_base": int(tot["n_near_base"]),
            # the frames finray predict does not flag near_base
            "unflagged": {
                c: (int(r[c]) if c == "n" else float(r[c]))
                for _, r in metrics[
                    (metrics["context"] == "unflagged") & (metrics["context_objects"] == k)
                ].iterrows()
                for c in ("n", "mse_N2", "rmse_N", "nrmse_pct", "coverage_pct")
            },
            "paper_mse_N2": paper_mse_N2().get(int(k)),
            "per_object": {
                r["test"]: {
                    c: float(r[c]) for c in ("mse_N2", "rmse_N", "nrmse_pct", "coverage_pct")
                }
                for _, r in g[g["test"] != "all"].iterrows()
            },
            "n_fits": sum(c["context_objects"] == int(k) for c in cals),
            # per phase of the takes (every height, and the face from phase_min_height_mm)
            **{
                key: {
                    r["test"]: {
                        c: (int(r[c]) if c == "n" else float(r[c]))
                        for c in ("n", "rmse_N", "nrmse_pct", "max_sensor_N", "coverage_pct")
                    }
                    for _, r in metrics[
                        (metrics["context"] == name) & (metrics["context_objects"] == k)
                    ].iterrows()
                }
                for key, name in (("per_phase", "by_phase"), ("per_phase_face", "by_phase_face"))
            },
            # per contact height of the takes: NRMSE in % of that height's largest force
            "per_height": {
                r["test"]: {
                    c: float(r[c]) for c in ("rmse_N", "nrmse_pct", "max_sensor_N", "coverage_pct")
                }
                for _, r in metrics[
                    (metrics["context"] == "by_height") & (metrics["context_objects"] == k)
                ].iterrows()
            },
        }
    mse = [by_k[k]["mse_N2"] for k in sorted(by_k, key=int)]
    fits = [
        {
            "context_objects": c["context_objects"],
            "context": c["context"],
            "fitted_on": c["fitted_on"],
            "n_frames": c["n_frames"],
            "summary": c["summary"],
            "diagnostics": c["diagnostics"],
            "cross_fit": c.get("cross_fit"),
            "near_base_frames": c.get("near_base_frames", 0),
        }
        for c in cals
    ]
    lab_k = [k for k in by_k if int(k) > 0]
    return {
        "emulated": True,
        "level": cfg.level,
        "by_context": by_k,
        "error_falls": bool(all(a > b for a, b in zip(mse, mse[1:]))),
        "lab_coverage_pct_with_context": (
            float(
                np.average(
                    [by_k[k]["coverage_pct"] for k in lab_k],
                    weights=[by_k[k]["n_frames"] for k in lab_k],
                )
            )
            if lab_k
            else None
        ),
        "simulated_test": sim,
        "diagnostics_ok": bool(all(c["diagnostics"]["ok"] for c in cals)),
        "fits": fits,
        "config": json.loads(json.dumps(asdict(cfg))),
    }


def write_outputs(result: dict, out: dict) -> None:
    """metrics.csv, frames.csv, summary.json, calibrations.json (every posterior with its
    diagnostics) and corner.pdf (one page per fit)."""
    from matplotlib.backends.backend_pdf import PdfPages

    from .calibration import corner_figure

    result["metrics"].to_csv(out["metrics"], index=False, float_format="%.6g")
    result["frames"].to_csv(out["frames"], index=False, float_format="%.6g")
    Path(out["summary"]).write_text(json.dumps(result["summary"], indent=1))
    Path(out["calibrations"]).write_text(json.dumps(result["calibrations"]))
    import matplotlib.pyplot as plt

    with PdfPages(out["corner"]) as pdf:
        for cal in result["calibrations"]:
            fig = corner_figure(
                cal,
                f"{cal['context_objects']} context object(s): {cal['context']} "
                f"({cal['fitted_on']}; emulated lab)",
            )
            pdf.savefig(fig, bbox_inches="tight")
            plt.close(fig)


def sim2real_figure(frames: pd.DataFrame, summary: dict, path) -> None:
    """The paper's Fig. 10 on the emulated takes: per context size (rows) and test
    object (columns), the sensor's force and the calibrated prediction with its
    interval against time (the object's takes one after another; the first context
    combination that leaves the object out)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ks = sorted(frames["context_objects"].unique())
    groups = sorted(frames["group"].unique())
    fig, axes = plt.subplots(
        len(ks),
        len(groups),
        figsize=(3.6 * len(groups), 2.4 * len(ks) + 0.5),
        squeeze=False,
        sharey=True,
    )
    level = summary.get("level", 0.9)
    for i, k in enumerate(ks):
        for j, grp in enumerate(groups):
            ax = axes[i, j]
            fk = frames[(frames["context_objects"] == k) & (frames["group"] == grp)]
            if fk.empty:
                ax.set_axis_off()
                ax.text(
                    0.5, 0.5, f"{grp}: context", ha="center", transform=ax.transAxes, fontsize=8
                )
                continue
            g = fk[fk["context"] == sorted(fk["context"].unique())[0]]
            t0, ticks = 0.0, []
            for take, gt in g.groupby("take", sort=True):
                t = gt["t_s"].to_numpy() - gt["t_s"].min() + t0
                ax.fill_between(
                    t,
                    gt["lo_N"],
                    gt["hi_N"],
                    color="C0",
                    alpha=0.25,
                    lw=0,
                    label=f"{level:.0%} interval" if t0 == 0 else None,
                )
                ax.plot(t, gt["sensor_N"], color="k", lw=0.8, label="sensor" if t0 == 0 else None)
                ax.plot(
                    t, gt["pred_N"], color="C3", lw=0.9, label="prediction" if t0 == 0 else None
                )
                ticks.append((t0, take))
                t0 = t[-1] + 0.5
            for x0, _ in ticks[1:]:
                ax.axvline(x0 - 0.25, color="0.8", lw=0.6)
            inside = ((g["sensor_N"] >= g["lo_N"]) & (g["sensor_N"] <= g["hi_N"])).mean()
            m = force_metrics(g["sensor_N"], g["pred_N"])
            ax.set_title(
                f"{grp} | context: {g['context'].iloc[0]}\nMSE {m['mse_N2']:.3f} N², "
                f"NRMSE {m['nrmse_pct']:.1f} %, inside {100 * inside:.0f} %",
                fontsize=7,
            )
            ax.tick_params(labelsize=7)
            if j == 0:
                ax.set_ylabel(f"{k} context object(s)\nforce (N)", fontsize=8)
            if i == len(ks) - 1:
                ax.set_xlabel("time, takes one after another (s)", fontsize=8)
            if i == 0 and j == 0:
                ax.legend(fontsize=6, loc="upper left")
    fig.suptitle(
        "Sim-to-real on the EMULATED lab takes (not recordings): sensor vs calibrated prediction",
        fontsize=9,
    )
    fig.tight_layout()
    from ..plotting import save_figure

    save_figure(fig, path)
