"""Sim-to-real on many emulated rigs: each figure per rig, its mean and range over them.

:func:`rigs_table` reads each rig's ``summary.json`` of :func:`finray.sim2real.experiment.
run_sim2real`; :func:`write_rigs` writes the table (CSV, Markdown), a summary (JSON:
per context count the mean, range and pooled interval coverage over the rigs, and
whether every rig meets the targets) and a figure of error and coverage against the
context count, one line per rig. Every rig is emulated (:mod:`finray.emulator.rigs`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd


def rigs_table(summaries: dict[str, dict]) -> pd.DataFrame:
    """One row per rig and context count: NRMSE (%), MSE (N^2), coverage (%), frames, and
    on the frames ``finray predict`` does not flag ``near_base`` (``unflagged_``; every
    frame for a summary written before the flag)."""
    rows = []
    for rig, s in summaries.items():
        for k, m in sorted(s["by_context"].items(), key=lambda kv: int(kv[0])):
            ok = m.get("unflagged") or {"nrmse_pct": m["nrmse_pct"], "n": m["n_frames"]}
            rows.append(
                {
                    "rig": rig,
                    "context_objects": int(k),
                    "nrmse_pct": m["nrmse_pct"],
                    "mse_N2": m["mse_N2"],
                    "coverage_pct": m["coverage_pct"],
                    "n_frames": int(m["n_frames"]),
                    "unflagged_nrmse_pct": ok["nrmse_pct"],
                    "unflagged_n_frames": int(ok["n"]),
                }
            )
    return pd.DataFrame(rows)


def rigs_heights(summaries: dict[str, dict]) -> dict:
    """Per rig and context count, each contact height's NRMSE (% of that height's largest
    force) and interval coverage (%): ``{rig: {k: {height: {"nrmse_pct", "coverage_pct"}}}}``
    (empty for a summary written before heights were recorded)."""
    return {
        rig: {
            k: {
                h: {c: m[c] for c in ("nrmse_pct", "coverage_pct")}
                for h, m in sorted(node.get("per_height", {}).items(), key=lambda kv: float(kv[0]))
            }
            for k, node in sorted(s["by_context"].items(), key=lambda kv: int(kv[0]))
        }
        for rig, s in summaries.items()
    }


def rigs_phases(summaries: dict[str, dict], key: str = "per_phase_face") -> pd.DataFrame:
    """One row per rig, context count and phase of the takes (:mod:`finray.sim2real.phases`):
    NRMSE (% of the largest force of every phase's frames), coverage (%) and frames, of the takes at the
    face's heights (``per_phase_face``) or of every take (``per_phase``); empty for
    summaries written without phases."""
    rows = [
        {
            "rig": rig,
            "context_objects": int(k),
            "phase": ph,
            **{c: m[c] for c in ("nrmse_pct", "coverage_pct", "n")},
        }
        for rig, s in summaries.items()
        for k, node in s["by_context"].items()
        for ph, m in node.get(key, {}).items()
        if ph != "rest"
    ]
    return pd.DataFrame(
        rows, columns=["rig", "context_objects", "phase", "nrmse_pct", "coverage_pct", "n"]
    )


def phases_summary(phases: pd.DataFrame, max_nrmse_pct: float = 5.0) -> dict:
    """Per context count and phase: NRMSE's largest over the rigs and the coverage pooled
    over their frames; whether every rig is within ``max_nrmse_pct`` in every phase."""
    out = {}
    for (k, ph), g in phases.groupby(["context_objects", "phase"]):
        out.setdefault(str(k), {})[ph] = {
            "nrmse_pct_max": float(g["nrmse_pct"].max()),
            "nrmse_pct_mean": float(g["nrmse_pct"].mean()),
            "coverage_pct_pooled": float((g["coverage_pct"] * g["n"]).sum() / g["n"].sum()),
            "worst_rig": str(g.loc[g["nrmse_pct"].idxmax(), "rig"]),
        }
    top = (
        phases[phases["context_objects"] == phases["context_objects"].max()]
        if len(phases)
        else phases
    )
    return {
        "by_context": out,
        "max_nrmse_pct": max_nrmse_pct,
        "all_within_target": bool(len(top) and (top["nrmse_pct"] <= max_nrmse_pct).all()),
    }


def phases_figure(phases: pd.DataFrame, level: float, path) -> None:
    """NRMSE and coverage per phase of the takes (loading, hold, unloading, second cycle),
    a bar per rig, one panel pair per context count (PNG)."""
    from ..plotting import pyplot

    from .phases import PHASES

    plt = pyplot()
    ks = sorted(phases["context_objects"].unique()) if len(phases) else [0]
    fig, axes = plt.subplots(2, len(ks), figsize=(3.2 * len(ks), 4.6), squeeze=False, sharey="row")
    order = [p for p in PHASES if p != "rest"]
    rigs = list(dict.fromkeys(phases["rig"])) if len(phases) else []
    width = 0.8 / max(len(rigs), 1)
    for j, k in enumerate(ks):
        g = phases[phases["context_objects"] == k]
        for i, rig in enumerate(rigs):
            r = g[g["rig"] == rig].set_index("phase").reindex(order)
            x = np.arange(len(order)) + (i - (len(rigs) - 1) / 2) * width
            for row, col in enumerate(("nrmse_pct", "coverage_pct")):
                axes[row, j].bar(x, r[col], width, label=rig)
        axes[0, j].set_title(f"{k} context object(s)", fontsize=8)
        axes[1, j].axhline(100 * level, color="grey", ls="--", lw=1)
        for row in range(2):
            axes[row, j].set_xticks(range(len(order)))
            axes[row, j].set_xticklabels(order, rotation=30, fontsize=7)
    axes[0, 0].set_ylabel("force NRMSE (%)")
    axes[1, 0].set_ylabel(f"inside the {level:.0%} interval (%)")
    axes[1, 0].set_ylim(0, 100)
    if rigs:
        axes[0, -1].legend(fontsize=6, title="emulated rig", title_fontsize=6)
    fig.suptitle("Sim-to-real by phase of the takes (emulated rigs)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def rigs_summary(table: pd.DataFrame, level: float, max_nrmse_pct: float = 5.0) -> dict:
    """Per context count: NRMSE mean and range over the rigs, the coverage pooled over
    every rig's frames; per rig, whether the error falls with each context object and the
    NRMSE with the most context objects is within ``max_nrmse_pct``, on every frame and
    on the frames not flagged ``near_base`` (``unflagged_``)."""
    by_k = {}
    for k, g in table.groupby("context_objects"):
        by_k[str(k)] = {
            "nrmse_pct_mean": float(g["nrmse_pct"].mean()),
            "nrmse_pct_min": float(g["nrmse_pct"].min()),
            "nrmse_pct_max": float(g["nrmse_pct"].max()),
            "coverage_pct_pooled": float(
                (g["coverage_pct"] * g["n_frames"]).sum() / g["n_frames"].sum()
            ),
            "coverage_pct_min": float(g["coverage_pct"].min()),
            "coverage_pct_max": float(g["coverage_pct"].max()),
        }
    per_rig = {}
    for rig, g in table.groupby("rig", sort=False):
        g = g.sort_values("context_objects")
        e, u = g["nrmse_pct"].to_numpy(), g["unflagged_nrmse_pct"].to_numpy()
        per_rig[rig] = {
            "error_falls": bool(np.all(np.diff(e) < 0)),
            "nrmse_pct_most_context": float(e[-1]),
            "within_target": bool(e[-1] <= max_nrmse_pct),
            "unflagged_error_falls": bool(np.all(np.diff(u) < 0)),
            "unflagged_within_target": bool(u[-1] <= max_nrmse_pct),
            "unflagged_nrmse_pct": [float(v) for v in u],
            # the tested frames flagged near_base (a frame once per context that leaves it out)
            "near_base_frames": [int(v) for v in g["n_frames"] - g["unflagged_n_frames"]],
            # per context count (0, 1, ...), and the frames behind each coverage
            "nrmse_pct": [float(v) for v in e],
            "coverage_pct": [float(v) for v in g["coverage_pct"]],
            "n_frames": [int(v) for v in g["n_frames"]],
        }
    return {
        "emulated": True,
        "rigs": list(per_rig),
        "level": level,
        "by_context": by_k,
        "per_rig": per_rig,
        "max_nrmse_pct": max_nrmse_pct,
        "all_fall": all(r["error_falls"] for r in per_rig.values()),
        "all_within_target": all(r["within_target"] for r in per_rig.values()),
        "unflagged_all_fall": all(r["unflagged_error_falls"] for r in per_rig.values()),
        "unflagged_all_within_target": all(r["unflagged_within_target"] for r in per_rig.values()),
    }


def rigs_figure(table: pd.DataFrame, level: float, path) -> None:
    """NRMSE and interval coverage against the number of context objects, a line per rig
    (dashed: the NRMSE on the frames not flagged ``near_base``, where any is; ``path``: a
    PDF, a PNG beside it; or a PNG alone)."""
    from ..plotting import pyplot, save_figure

    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(8, 3.2))
    for rig, g in table.groupby("rig", sort=False):
        g = g.sort_values("context_objects")
        style = {"lw": 2.2, "color": "k"} if rig == "default" else {"lw": 1.2}
        for ax, col in zip(axes, ("nrmse_pct", "coverage_pct")):
            (line,) = ax.plot(g["context_objects"], g[col], "o-", label=rig, **style)
        if (g["unflagged_n_frames"] < g["n_frames"]).any():
            axes[0].plot(
                g["context_objects"],
                g["unflagged_nrmse_pct"],
                "s--",
                ms=3,
                color=line.get_color(),
                lw=style["lw"] * 0.7,
                label=f"{rig}, not near_base",
            )
    axes[0].set_ylabel("force NRMSE (%)")
    axes[0].set_ylim(bottom=0)
    axes[1].axhline(100 * level, color="grey", ls="--", lw=1)
    axes[1].set_ylabel(f"frames inside the {level:.0%} interval (%)")
    axes[1].set_ylim(0, 100)
    for ax in axes:
        ax.set_xlabel("context objects")
        ax.set_xticks(sorted(table["context_objects"].unique()))
    axes[0].legend(fontsize=6, title="emulated rig", title_fontsize=6)
    fig.suptitle("Sim-to-real on emulated rigs (the configured one and drawn ones)", fontsize=9)
    fig.tight_layout()
    path = Path(path)
    if path.suffix == ".png":
        fig.savefig(path, dpi=150)
        plt.close(fig)
    else:
        save_figure(fig, path)


def write_rigs(summaries: dict[str, dict], rigs: dict, out) -> dict:
    """The table, summary and figure (``out``: json, table, csv, figure paths); ``rigs``:
    each drawn rig's settings, recorded beside its figures."""
    table = rigs_table(summaries)
    level = float(next(iter(summaries.values())).get("level", 0.9))
    summary = rigs_summary(table, level) | {"settings": rigs, "per_height": rigs_heights(summaries)}
    table.to_csv(out["csv"], index=False)
    names = {
        "nrmse_pct": "NRMSE %",
        "unflagged_nrmse_pct": "NRMSE % not near_base",
        "coverage_pct": "coverage %",
    }
    wide = table.pivot(index="rig", columns="context_objects", values=list(names))
    wide = wide.loc[list(summaries)]
    wide.columns = [f"{names[c]}, {k} context" for c, k in wide.columns]
    # with no context every frame is tested once
    first = table[table["context_objects"] == table["context_objects"].min()].set_index("rig")
    flagged = first["n_frames"] - first["unflagged_n_frames"]
    wide.insert(0, "frames near_base", flagged.loc[list(summaries)].astype(int))
    Path(out["table"]).write_text(
        "# Sim-to-real on emulated rigs\n\nEvery rig is emulated (finray.emulator.rigs): `default` is "
        "config `lab:`, the others are drawn from `lab.rigs`. *not near_base*: the frames "
        "`finray predict` does not flag `near_base`; frames near_base: how many it flags "
        "(each frame once).\n\n" + wide.round(2).to_markdown() + "\n"
    )
    phases = rigs_phases(summaries)
    summary["phases"] = phases_summary(phases)
    summary["phases"]["per_rig"] = {
        rig: {
            str(k): {
                r["phase"]: {c: r[c] for c in ("nrmse_pct", "coverage_pct", "n")}
                for _, r in gk.iterrows()
            }
            for k, gk in g.groupby("context_objects")
        }
        for rig, g in phases.groupby("rig", sort=False)
    }
    if len(phases):
        wide = phases.pivot_table(
            index=["rig", "context_objects"], columns="phase", values="nrmse_pct"
        )
        text = Path(out["table"]).read_text()
        Path(out["table"]).write_text(
            text
            + "\n## By phase of the takes\n\nNRMSE % of the takes' largest force (every phase's frames), the takes "
            "at the face's heights (evaluate.sim2real.phase_min_height_mm and up).\n\n"
            + wide.round(2).to_markdown()
            + "\n"
        )
    Path(out["json"]).write_text(json.dumps(summary, indent=1, default=float))
    rigs_figure(table, level, out["figure"])
    if out.get("phases"):
        phases_figure(phases, level, out["phases"])
    return summary


def write_print_time(pairs: dict, out, max_nrmse_pct: float = 5.0) -> dict:
    """The print-time study's table (``studies/print_time``): ``pairs`` maps (variant,
    rig) to the summary.json paths of its time-dependent and static sim-to-real; per
    variant, rig, calibration, context count and phase of the takes at the face's
    heights (``per_phase_face``), NRMSE and coverage. Writes ``out``'s csv, table (Markdown),
    json (per calibration, context count and phase: the largest NRMSE over variants and
    rigs, the coverage pooled over their frames; whether each is within
    ``max_nrmse_pct`` on every rig and variant) and figure."""
    rows = []
    for (variant, rig), paths in pairs.items():
        for cal, path in zip(("time-dependent", "static"), paths):
            ph = rigs_phases({rig: json.loads(Path(path).read_text())})
            rows += [{"variant": variant, "calibration": cal, **r} for r in ph.to_dict("records")]
    table = pd.DataFrame(rows)
    table.to_csv(out["csv"], index=False, float_format="%.4g")
    summary = {"emulated": True, "max_nrmse_pct": max_nrmse_pct, "by_calibration": {}}
    for cal, g in table.groupby("calibration"):
        node = summary["by_calibration"].setdefault(cal, {})
        for (k, ph), h in g.groupby(["context_objects", "phase"]):
            node.setdefault(str(k), {})[ph] = {
                "nrmse_pct_max": float(h["nrmse_pct"].max()),
                "nrmse_pct_mean": float(h["nrmse_pct"].mean()),
                "coverage_pct_pooled": float((h["coverage_pct"] * h["n"]).sum() / h["n"].sum()),
                "worst": f"{h.loc[h['nrmse_pct'].idxmax(), 'variant']} "
                f"{h.loc[h['nrmse_pct'].idxmax(), 'rig']}",
            }
        top = g[g["context_objects"] == g["context_objects"].max()]
        node["all_within_target"] = bool((top["nrmse_pct"] <= max_nrmse_pct).all())
    wide = table.pivot_table(
        index=["calibration", "context_objects", "variant", "rig"],
        columns="phase",
        values="nrmse_pct",
    )
    cov = table.pivot_table(
        index=["calibration", "context_objects"], columns="phase", values="coverage_pct"
    )
    Path(out["table"]).write_text(
        "# Sim-to-real by phase: the time-dependent calibration and the static one\n\n"
        "Every rig is emulated. NRMSE % of the takes' largest force (every phase's frames), "
        "the takes at the face's heights (evaluate.sim2real.phase_min_height_mm and up).\n\n"
        + wide.round(2).to_markdown()
        + "\n\n## Interval coverage (%), mean over variants and rigs\n\n"
        + cov.round(1).to_markdown()
        + "\n"
    )
    Path(out["json"]).write_text(json.dumps(summary, indent=1))
    _print_time_figure(table, out["figure"])
    return summary


def _print_time_figure(table: pd.DataFrame, path) -> None:
    """Per phase, each (variant, rig)'s NRMSE with the most context objects: static
    against time-dependent (PNG)."""
    from ..plotting import pyplot

    from .phases import PHASES

    plt = pyplot()
    order = [p for p in PHASES if p != "rest"]
    k = table["context_objects"].max()
    fig, ax = plt.subplots(figsize=(6.4, 3.2))
    for i, (cal, marker) in enumerate((("static", "o"), ("time-dependent", "s"))):
        g = table[(table["calibration"] == cal) & (table["context_objects"] == k)]
        x = np.array([order.index(p) for p in g["phase"]]) + (i - 0.5) * 0.3
        ax.plot(x, g["nrmse_pct"], marker, ms=4, alpha=0.7, ls="none", label=f"{cal} calibration")
    ax.axhline(5.0, color="grey", ls="--", lw=1)
    ax.set_xticks(range(len(order)))
    ax.set_xticklabels(order)
    ax.set_ylabel("force NRMSE (%)")
    ax.set_ylim(bottom=0)
    ax.set_title(
        f"Emulated viscoelastic print, {k} context object(s): each rig and training", fontsize=9
    )
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)
