"""Figures of the paper's experiments (PDF + PNG), from an experiment's outputs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..plotting import pyplot, save_figure
from .experiments import load_examples
from .tables import headline_rows

COLOURS = {
    "fea": "black",
    "plain": "tab:blue",
    "occlusion": "tab:orange",
    "pitch": "tab:green",
    "camera": "tab:purple",
    "baseline": "tab:gray",
}
LABELS = {
    "fea": "FEA",
    "plain": "CNN",
    "occlusion": "CNN, occlusion-trained",
    "pitch": "CNN, pitch-augmented",
    "camera": "CNN, camera views",
    "baseline": "ridge on front edge",
}
#: the names in a panel's title that are not the model's own (one word each, so that several fit)
SHORT = {"plain": "CNN", "baseline": "ridge"}


def _predictors(frames: pd.DataFrame) -> list[str]:
    return [c[5:] for c in frames.columns if c.startswith("pred_") and not c.startswith("pred_fy_")]


def _force_panel(
    ax, g: pd.DataFrame, predictors, metrics: pd.DataFrame | None = None, condition=None, group=None
):
    """Force over the frames of a test video (scenes one after another)."""
    x = np.arange(len(g))
    ax.plot(x, g["fx_N"], color=COLOURS["fea"], lw=2.0, label=LABELS["fea"])
    for p in predictors:
        ax.plot(
            x,
            g[f"pred_{p}"],
            color=COLOURS.get(p, None),
            lw=1.0,
            ls="--" if p == "baseline" else "-",
            label=LABELS.get(p, p),
        )
    # scene boundaries (the heights)
    starts = np.flatnonzero(
        np.r_[True, g["scene_id"].to_numpy()[1:] != g["scene_id"].to_numpy()[:-1]]
    )
    for s in starts[1:]:
        ax.axvline(s, color="0.8", lw=0.8)
    for s, sid in zip(starts, g["scene_id"].to_numpy()[starts]):
        ax.text(
            s + 3,
            ax.get_ylim()[1] * 0.97 if ax.get_ylim()[1] > 0 else 0,
            f"{g['height_mm'].iloc[s]:g} mm",
            fontsize=7,
            va="top",
            color="0.4",
        )
    ax.set_xlabel("frame")
    if metrics is not None:
        sel = metrics[(metrics["condition"] == condition) & (metrics["group"] == group)]
        parts = [
            f"{SHORT.get(r.predictor, r.predictor)} {r.nrmse_pct:.1f}%"
            for r in sel.itertuples()
            if r.predictor in predictors
        ]
        lines = [", ".join(parts[i : i + 3]) for i in range(0, len(parts), 3)]  # 3 a line
        ax.set_title("\n".join([str(group), "NRMSE " + "\n".join(lines)]), fontsize=8)


def _triptych(inp, true, pred, mask, vmax: float) -> np.ndarray:
    """RGB strip: network input (grey) | FEA log-stress | predicted log-stress (inferno,
    shown inside the FEA mask), with a 2 px white gap between them."""
    from matplotlib import colormaps

    cmap = colormaps["inferno"]
    grey = np.repeat((np.asarray(inp, float) / 255.0)[..., None], 3, axis=2)
    t = cmap(np.clip(true / vmax, 0, 1))[..., :3]
    p = cmap(np.clip(pred * mask / vmax, 0, 1))[..., :3]
    gap = np.ones((grey.shape[0], 2, 3))
    return np.concatenate([grey, gap, t, gap, p], axis=1)


def _stress_row(axes, ex: dict, net: str, vmax: float, title_prefix=""):
    """Input, FEA stress, predicted stress of each example (one example per axis)."""
    for j, ax in enumerate(axes):
        ax.imshow(
            _triptych(
                ex["input"][j], ex["stress_true"][j], ex[f"stress_{net}"][j], ex["mask"][j], vmax
            ),
            interpolation="nearest",
        )
        ax.set_title(
            f"{title_prefix}{ex['label'][j]}: {ex['fx_N'][j]:.2f} N (FEA), "
            f"{ex[f'pred_{net}'][j]:.2f} N (CNN)\ninput | FEA stress | CNN stress",
            fontsize=7,
        )
        ax.axis("off")


def _force_and_stress_grid(exp_dir, group_col: str, extra_cols: int = 0):
    """Figure of an experiment with one condition: force over the test frames per group
    (top row) and FEA vs network stress maps at the largest force (bottom row), plus
    ``extra_cols`` empty columns; returns ``(fig, gridspec, groups)``."""
    plt = pyplot()
    exp_dir = Path(exp_dir)
    frames = pd.read_csv(exp_dir / "frames.csv")
    if "path" in frames:  # the test video: shard inputs of every frame
        frames = frames[frames["path"] == "shard"].reset_index(drop=True)
    metrics = headline_rows(pd.read_csv(exp_dir / "metrics.csv"))
    ex = load_examples(exp_dir / "examples.npz")["all"]
    preds = _predictors(frames)
    groups = sorted(frames[group_col].astype(str).unique())
    n = len(groups)
    fig = plt.figure(figsize=(3.4 * (n + extra_cols), 6.2))
    gs = fig.add_gridspec(2, n + extra_cols, height_ratios=[1, 1.3])
    for i, grp in enumerate(groups):
        ax = fig.add_subplot(gs[0, i])
        _force_panel(
            ax,
            frames[frames[group_col].astype(str) == grp].reset_index(drop=True),
            preds,
            metrics,
            "all",
            grp,
        )
        if i == 0:
            ax.set_ylabel("Fx on the finger (N)")
            ax.legend(fontsize=7, loc="lower right")
    vmax = float(max(ex["stress_true"].max(), 1e-6))
    _stress_row(
        [fig.add_subplot(gs[1, i]) for i in range(min(n, len(ex["label"])))], ex, preds[0], vmax
    )
    return fig, gs, groups


def generalisation_figure(exp_dir, out_pdf, group_col: str, title: str):
    """Shape generalisation: force over the test frames per group (network, baseline,
    FEA), and stress maps FEA vs network at the largest force of each group."""
    fig, _, _ = _force_and_stress_grid(exp_dir, group_col)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    save_figure(fig, out_pdf)


def material_figure(exp_dir, out_pdf, fea_seconds: dict[str, float], net_ms: float):
    """Material generalisation, with the FEA time per material beside the network's."""
    fig, gs, mats = _force_and_stress_grid(exp_dir, "material", extra_cols=1)
    ax = fig.add_subplot(gs[0, len(mats)])
    names = mats + ["CNN"]
    vals = [fea_seconds.get(m, np.nan) for m in mats] + [net_ms / 1e3]
    bars = ax.bar(names, vals, color=["0.5"] * len(mats) + [COLOURS["plain"]])
    ax.bar_label(bars, labels=[f"{v:.1f} s" for v in vals[:-1]] + [f"{net_ms:.1f} ms"], fontsize=7)
    ax.tick_params(axis="x", labelrotation=30, labelsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("seconds (FEA: per scene; CNN: per frame)")
    ax.set_title("time per material", fontsize=8)
    fig.suptitle(
        "Material generalisation: ring in steel, NinjaFlex and neoprene (no retraining)",
        fontsize=10,
    )
    fig.tight_layout()
    save_figure(fig, out_pdf)


def condition_figure(
    exp_dir,
    out_pdf,
    title: str,
    xlabel: str,
    threshold_pct: float | None = None,
    example_net: str | None = None,
):
    """Occlusion or pitch: force NRMSE per condition and predictor, with the inputs
    and stress maps of each condition."""
    plt = pyplot()
    exp_dir = Path(exp_dir)
    metrics = headline_rows(pd.read_csv(exp_dir / "metrics.csv"))
    ex = load_examples(exp_dir / "examples.npz")
    allm = metrics[metrics["group"] == "all"]
    conds = list(dict.fromkeys(allm["condition"].astype(str)))
    preds = list(dict.fromkeys(allm["predictor"]))
    fig = plt.figure(figsize=(max(8, 1.9 * len(conds)), 5.8))
    gs = fig.add_gridspec(2, len(conds), height_ratios=[1.3, 1])
    nets = [p for p in preds if p != "baseline"]
    net = example_net if example_net in nets else nets[-1]
    for j, c in enumerate(conds):
        e = ex[c]
        ax = fig.add_subplot(gs[0, j])
        ax.imshow(
            _triptych(
                e["input"][0],
                e["stress_true"][0],
                e[f"stress_{net}"][0],
                e["mask"][0],
                float(max(e["stress_true"].max(), 1e-6)),
            ),
            interpolation="nearest",
        )
        ax.set_title(
            f"{c}: {e['fx_N'][0]:.2f} N (FEA), {e[f'pred_{net}'][0]:.2f} N\n"
            "input | FEA | CNN stress",
            fontsize=7,
        )
        ax.axis("off")
    ax = fig.add_subplot(gs[1, :])
    x = np.arange(len(conds))
    width = 0.8 / len(preds)
    for i, p in enumerate(preds):
        v = [
            float(
                allm[(allm["condition"].astype(str) == c) & (allm["predictor"] == p)][
                    "nrmse_pct"
                ].iloc[0]
            )
            for c in conds
        ]
        bars = ax.bar(
            x + (i - (len(preds) - 1) / 2) * width,
            v,
            width,
            color=COLOURS.get(p),
            label=LABELS.get(p, p),
        )
        ax.bar_label(bars, fmt="%.1f", fontsize=6)
    if threshold_pct is not None:
        ax.axhline(threshold_pct, color="k", ls=":", lw=1, label=f"{threshold_pct:g}% (usable)")
    ax.set_xticks(x, conds)
    ax.set_yscale("log")
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    ax.yaxis.set_major_formatter(ScalarFormatter())
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel(xlabel)
    ax.set_ylabel("force NRMSE (% of max force)")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.005, 1.0))
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    save_figure(fig, out_pdf)


def speed_figure(speed: dict, out_pdf):
    """FEA s/scene vs network ms/frame, and the job time per pipeline stage and per study
    (apart), with the DAG's wall time."""
    plt = pyplot()
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.4))
    fea = speed["fea_seconds_per_scene"]
    names = list(fea) + ["CNN (1 thread)"]
    vals = [fea[k]["median"] for k in fea] + [speed["network_ms_per_frame"] / 1e3]
    bars = ax[0].bar(names, vals, color=["0.5"] * len(fea) + [COLOURS["plain"]])
    ax[0].bar_label(
        bars, labels=[f"{v:.1f} s" for v in vals[:-1]] + [f"{vals[-1] * 1e3:.1f} ms"], fontsize=7
    )
    ax[0].set_yscale("log")
    ax[0].set_ylabel("s (FEA: median per scene; CNN: per frame)")
    ax[0].tick_params(axis="x", labelsize=8)
    st, studies = speed["stages"], speed["studies"]
    # job durations (one thread per job); Snakemake's sampled cpu_time misses short jobs
    bars = ax[1].barh(
        list(st) + [f"study: {k}" for k in studies],
        [st[k]["wall_s"] / 60 for k in st] + [v["wall_s"] / 60 for v in studies.values()],
        color=["tab:blue"] * len(st) + ["0.6"] * len(studies),
    )
    ax[1].bar_label(bars, fmt="%.1f", fontsize=7)
    ax[1].set_xlabel("minutes (sum of job times, one thread each)")
    ax[1].tick_params(axis="y", labelsize=7)
    ax[1].invert_yaxis()
    dag = speed["dag"]
    ax[1].set_title(
        f"pipeline stages (blue), studies (grey); whole DAG {dag['wall_s'] / 60:.1f} min wall",
        fontsize=8,
    )
    fig.suptitle("Speed: FEA against the network, and the pipeline's stages", fontsize=10)
    fig.tight_layout()
    save_figure(fig, out_pdf)


def annotated_figure(
    model_path,
    render_index,
    lab_video,
    lab_ingest_json,
    out_pdf,
    pitch_deg: float = 15.0,
    distance_mm: float = 200.0,
):
    """Two frames as ``finray predict --annotate`` draws them (:mod:`finray.annotate`):
    a held-out shape's pyvista render (the frame of the largest true force at
    ``pitch_deg`` and ``distance_mm``) and a frame of an emulated lab take (of every 30th
    frame, the one of the largest predicted force), the latter segmented by the finger
    colour its ingest learned, as ``finray predict --calibration`` does."""
    import json

    import imageio.v3 as iio

    from ..annotate import annotate_frame
    from ..media import video_frames
    from ..predictor import Predictor
    from ..recording.colour import ColourRange, segment_finger
    from ..render.scene import load_render_index

    p = Predictor(model_path, threads=1, backend="torchscript", roi_stride=1)

    def annotated(frame, mask, label, margin: float = 0.6):
        """Annotated around the network's window (``margin`` of its size each side)."""
        stress, f = p.run(p.network_input(mask))
        forces = {n: float(v) for n, v in zip(p.force_names, f[0])}
        c0, r0, c1, r1 = p.crop_box(mask)
        dc, dr = margin * (c1 - c0), 0.25 * margin * (r1 - r0)
        j0, i0 = max(int(c0 - dc), 0), max(int(r0 - dr), 0)
        j1, i1 = min(int(c1 + dc) + 1, frame.shape[1]), min(int(r1 + dr) + 1, frame.shape[0])
        box = (c0 - j0, r0 - i0, c1 - j0, r1 - i0)
        return annotate_frame(
            frame[i0:i1, j0:j1], mask[i0:i1, j0:j1], box, stress[0, 0], forces, None, label
        ), forces

    folder = Path(render_index).parent
    index = load_render_index(folder)
    fr = max(
        (
            f
            for f in index["frames"]
            if f["pitch_deg"] == pitch_deg and f["distance_mm"] == distance_mm
        ),
        key=lambda f: f["fx_N"],
    )
    rgb = iio.imread(folder / fr["image"])[..., :3]
    scene = index["scene"]
    left, _ = annotated(
        rgb,
        p.segment(rgb),
        f"{scene['object']}, pitch {pitch_deg:g} deg\nFEA fx {fr['fx_N']:.2f} N",
    )
    colour = ColourRange.from_take(json.loads(Path(lab_ingest_json).read_text())["colour"])
    best = None
    for k, f in enumerate(video_frames(lab_video)):
        if k % 30 or f.image is None:
            continue
        mask = segment_finger(f.image, colour)
        if mask is None:
            continue
        img, forces = annotated(f.image, mask, f"emulated rig, t = {f.t_s:.2f} s")
        if best is None or forces["fx_N"] > best[1]["fx_N"]:
            best = (img, forces)
    if best is None:
        raise ValueError(f"no frame of {lab_video} shows the finger's colour")
    plt = pyplot()
    fig, ax = plt.subplots(1, 2, figsize=(9, 4.6))
    for a, img, title in (
        (ax[0], left, "pyvista render of a held-out shape"),
        (ax[1], best[0], "emulated lab rig (not a recording)"),
    ):
        a.imshow(img)
        a.set_title(title, fontsize=9)
        a.axis("off")
    fig.suptitle(
        "finray predict --annotate: the camera model's stress map over the finger and its force",
        fontsize=10,
    )
    fig.tight_layout()
    save_figure(fig, out_pdf)


def face_figure(heights_csvs: dict[str, str], out_pdf, paper_band_mm=(20.0, 40.0)):
    """Contacts over the finger's face: the held-out shapes' force NRMSE (% of the largest
    |Fx| at that height) against the contact height (mm), one line per network and
    training (``heights_csvs``: a training's label, e.g. its seed, -> the shape
    experiment's ``heights.csv``), filled markers at heights no training scene used; and
    the largest |Fx| at each height. The paper's heights are shaded."""
    plt = pyplot()
    fig, (ax, axf) = plt.subplots(1, 2, figsize=(10, 4), gridspec_kw={"width_ratios": [1.6, 1]})
    styles = ["-", "--", ":", "-."]
    forces = None
    for k, (label, path) in enumerate(heights_csvs.items()):
        h = pd.read_csv(path)
        h = h[h["condition"].astype(str) == "all"]
        for p, g in h.groupby("predictor", sort=False):
            g = g.sort_values("height_mm")
            c = COLOURS.get(p)
            ax.plot(
                g["height_mm"],
                g["nrmse_pct"],
                color=c,
                ls=styles[k % len(styles)],
                lw=1.2,
                label=f"{LABELS.get(p, p)}, {label}" if len(heights_csvs) > 1 else LABELS.get(p, p),
            )
            un = g["unseen"].astype(bool).to_numpy()
            ax.scatter(g["height_mm"][un], g["nrmse_pct"][un], color=c, s=18, zorder=3)
            ax.scatter(
                g["height_mm"][~un],
                g["nrmse_pct"][~un],
                facecolors="white",
                edgecolors=c,
                s=18,
                zorder=3,
            )
        if forces is None:
            forces = h.drop_duplicates("height_mm").sort_values("height_mm")
    for a in (ax, axf):
        a.axvspan(*paper_band_mm, color="0.92", zorder=0)
        a.set_xlabel("contact height (mm above the clamped base)")
    ax.set_ylim(bottom=0)
    ax.set_ylabel("Fx NRMSE (% of the largest |Fx| at that height)")
    ax.set_title(
        "held-out shapes (filled: heights no training scene used;\nshaded: the paper's heights)",
        fontsize=8,
    )
    ax.legend(fontsize=6)
    axf.plot(forces["height_mm"], forces["max_true_N"], "k.-")
    axf.set_ylim(bottom=0)
    axf.set_ylabel("largest |Fx| of the held-out shapes (N)")
    fig.suptitle("Force error over the finger's front face", fontsize=10)
    fig.tight_layout()
    save_figure(fig, out_pdf)
