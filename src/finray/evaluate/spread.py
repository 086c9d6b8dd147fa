"""The spread study: every headline figure over training seeds and numeric types.

A figure from one training is one draw. The spread study (``workflow/rules/spread.smk``)
retrains every model per seed and numeric type (a *variant*, ``s<seed>_<type>``) and runs
every experiment and sim-to-real on each; this module reads their outputs back:

- :func:`headline_figures` -- one variant's figures, by name (force NRMSE in %,
  log-stress MSE, sim-to-real MSE in N^2 and coverage in %, the kept epoch);
  :func:`run_figures` the same from a finished run's ``summary.json``
- :func:`spread_table` -- per figure the default variant's value, mean, min, max, range
- :func:`write_spread` -- ``summary.json``, ``spread.csv``, ``spread.md`` and the figure
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from .summary import experiment_summary

#: (path key of experiment_summary, label): the shard inputs, and the rendered frames
#: through the Predictor where the experiment has them
_PATHS = ((None, ""), ("camera", " (camera path)"))


def headline_figures(
    exp_dirs: dict[str, str | Path], sim2real: dict, histories: dict[str, dict]
) -> dict[str, float]:
    """One variant's headline figures: ``{name: value}``.

    ``exp_dirs``: experiment -> its output folder (``metrics.csv``); ``sim2real``: its
    ``summary.json``; ``histories``: model -> its ``history.json``. Names read
    ``<experiment> | <condition> | <predictor> | <measure>`` (all test frames pooled),
    ``sim2real | <k> context | <measure>`` and ``train | <model> | <measure>``."""
    return _figures({e: experiment_summary(d) for e, d in exp_dirs.items()}, sim2real, histories)


def variant_figures(variant: str, experiments, sim2real, histories) -> tuple[dict, dict]:
    """One variant's headline figures (:func:`headline_figures`) and its histories, picked
    by ``/<variant>/`` from a rule's input lists: experiments' ``metrics.json``, sim-to-
    real ``summary.json`` files and ``history.json`` files."""
    mine = [p for p in experiments if f"/{variant}/" in p]
    exps = {Path(p).parent.name: Path(p).parent for p in mine}
    s2r = json.loads(next(Path(p) for p in sim2real if f"/{variant}/" in p).read_text())
    hist = {
        Path(p).parent.name: json.loads(Path(p).read_text())
        for p in histories
        if f"/{variant}/" in p
    }
    return headline_figures(exps, s2r, hist), hist


def rig_figures(rigs: dict) -> dict[str, float]:
    """A variant's figures on every emulated rig (a ``summary.json`` of
    :func:`finray.sim2real.rigs.write_rigs`): ``sim2real rigs | <rig> | <k> context |
    NRMSE %`` and ``coverage %``, and per context count the coverage pooled over the
    rigs' frames (``sim2real rigs | pooled | <k> context | coverage %``)."""
    out = {}
    for rig, r in rigs["per_rig"].items():
        for k, (e, c) in enumerate(zip(r["nrmse_pct"], r["coverage_pct"])):
            out[f"sim2real rigs | {rig} | {k} context | NRMSE %"] = e
            out[f"sim2real rigs | {rig} | {k} context | coverage %"] = c
    for k, m in rigs["by_context"].items():
        out[f"sim2real rigs | pooled | {k} context | coverage %"] = m["coverage_pct_pooled"]
    return {k: float(v) for k, v in out.items()}


def rig_acceptance(spread: dict, max_nrmse_pct: float) -> dict | None:
    """Sim-to-real on the emulated rigs over the variants (a spread ``summary.json``):
    per rig its NRMSE per context count (mean over the variants), whether that mean falls
    with each context object and is within ``max_nrmse_pct`` with the most, and in how
    many variants each holds; per context count the pooled coverage's mean and range.
    None where the study ran no rigs."""
    figs, variants = spread["figures"], spread["variants"]
    rigs = sorted(
        {n.split(" | ")[1] for n in figs if n.startswith("sim2real rigs | ")} - {"pooled"},
        key=lambda r: (r != "default", r),
    )
    if not rigs:
        return None
    per_rig = {}
    for rig in rigs:
        ks = sorted(
            {
                int(n.split(" | ")[2].split()[0])
                for n in figs
                if n.startswith(f"sim2real rigs | {rig} | ")
            }
        )
        e = np.array(
            [
                [figs[f"sim2real rigs | {rig} | {k} context | NRMSE %"][v] for k in ks]
                for v in variants
                if figs[f"sim2real rigs | {rig} | {ks[0]} context | NRMSE %"].get(v) is not None
            ],
            dtype=float,
        )
        mean = e.mean(axis=0)
        per_rig[rig] = {
            "nrmse_pct_mean": mean.tolist(),
            "nrmse_pct_min": e.min(axis=0).tolist(),
            "nrmse_pct_max": e.max(axis=0).tolist(),
            "n": len(e),
            "falls_on_mean": bool(np.all(np.diff(mean) < 0)),
            "within_target_on_mean": bool(mean[-1] <= max_nrmse_pct),
            "falls_in": int(np.all(np.diff(e, axis=1) < 0, axis=1).sum()),
            "within_target_in": int((e[:, -1] <= max_nrmse_pct).sum()),
        }
    pooled = {}
    for n, f in sorted(figs.items()):
        if n.startswith("sim2real rigs | pooled | "):
            k = n.split(" | ")[2].split()[0]
            pooled[k] = {c: f[c] for c in ("mean", "min", "max")}
    return {
        "rigs": rigs,
        "variants": variants,
        "max_nrmse_pct": max_nrmse_pct,
        "per_rig": per_rig,
        "coverage_pct_pooled": pooled,
    }


def run_figures(summary: dict) -> dict[str, float]:
    """The same figures (the experiments' and sim-to-real's) from a run's
    ``results/summary.json``: a finished run beside the study's variants."""
    return _figures(summary.get("experiments", {}), summary.get("sim2real") or {}, {})


def _figures(
    experiments: dict[str, dict], sim2real: dict, histories: dict[str, dict]
) -> dict[str, float]:
    out: dict[str, float] = {}
    for exp, summ in sorted(experiments.items()):
        for cond, preds in summ.items():
            for pred, node in preds.items():
                for key, label in _PATHS:
                    m = (node.get(key) or {}).get("all") if key else node.get("all")
                    if not m:
                        continue
                    name = f"{exp} | {cond} | {pred}{label}"
                    out[f"{name} | force NRMSE %"] = m["nrmse_pct"]
                    if m.get("stress_mse_log") is not None:
                        out[f"{name} | log-stress MSE"] = m["stress_mse_log"]
    for k, m in sorted(sim2real.get("by_context", {}).items(), key=lambda kv: int(kv[0])):
        for c, measure in (
            ("nrmse_pct", "NRMSE %"),
            ("mse_N2", "MSE N2"),
            ("coverage_pct", "coverage %"),
        ):
            out[f"sim2real | {k} context | {measure}"] = m[c]
    if sim2real.get("lab_coverage_pct_with_context") is not None:
        out["sim2real | 1+ context pooled | coverage %"] = sim2real["lab_coverage_pct_with_context"]
    sim = sim2real.get("simulated_test", {})
    if sim:
        out["sim2real | simulated held-out shapes, no context (calibrated) | NRMSE %"] = sim[
            "metrics"
        ]["nrmse_pct"]
        if "own_head" in sim:
            out["sim2real | simulated held-out shapes, the model's own head | NRMSE %"] = sim[
                "own_head"
            ]["nrmse_pct"]
    for model, h in sorted(histories.items()):
        i = h["best_epoch"] - 1
        out[f"train | {model} | kept epoch"] = float(h["best_epoch"])
        if h.get("val_force_rmse_N"):
            out[f"train | {model} | validation force RMSE N"] = h["val_force_rmse_N"][i]
        if h.get("train_seconds") is not None:
            out[f"train | {model} | training s"] = h["train_seconds"]
    return {k: float(v) for k, v in out.items() if v is not None and np.isfinite(v)}


def rigs_markdown(acc: dict) -> str:
    """:func:`rig_acceptance` as Markdown: per rig the mean NRMSE (min-max) per context
    count and in how many variants the error falls and is within target."""
    n = len(acc["variants"])
    ks = len(next(iter(acc["per_rig"].values()))["nrmse_pct_mean"])
    lines = [
        f"## Sim-to-real on the emulated rigs over the {n} variants",
        "",
        "force NRMSE %, mean (min-max) over the variants; falls: from each context "
        f"count to the next; within: <= {acc['max_nrmse_pct']:g} % with {ks - 1} context "
        "objects",
        "",
        "| rig | "
        + " | ".join(f"{k} context" for k in range(ks))
        + " | falls (mean / variants) | within (mean / variants) |",
        "|---" + "|--:" * (ks + 2) + "|",
    ]
    for rig, r in acc["per_rig"].items():
        cells = [
            f"{m:.2f} ({lo:.2f}-{hi:.2f})"
            for m, lo, hi in zip(r["nrmse_pct_mean"], r["nrmse_pct_min"], r["nrmse_pct_max"])
        ]
        lines.append(
            f"| {rig} | "
            + " | ".join(cells)
            + f" | {'yes' if r['falls_on_mean'] else 'no'} / {r['falls_in']} of {r['n']}"
            + f" | {'yes' if r['within_target_on_mean'] else 'no'} / {r['within_target_in']} of {r['n']} |"
        )
    lines += [
        "",
        "coverage of the intervals pooled over the rigs' frames, mean (min-max) over "
        "the variants: "
        + "; ".join(
            f"{k} context {c['mean']:.1f} ({c['min']:.1f}-{c['max']:.1f}) %"
            for k, c in sorted(acc["coverage_pct_pooled"].items(), key=lambda kv: int(kv[0]))
        ),
    ]
    return "\n".join(lines) + "\n"


def spread_table(figures: dict[str, dict[str, float]], default: str | None = None) -> pd.DataFrame:
    """Per figure (rows, in name order): each variant's value (a column per variant),
    ``default`` (that variant's value, NaN where it did not run), ``mean``, ``min``,
    ``max``, ``range`` (max - min) and ``n`` (variants with the figure)."""
    df = pd.DataFrame(figures).sort_index()
    v = df.to_numpy(dtype=float)
    stats = pd.DataFrame(
        {
            "default": df[default] if default in df else np.nan,
            "mean": np.nanmean(v, axis=1),
            "min": np.nanmin(v, axis=1),
            "max": np.nanmax(v, axis=1),
            "n": np.isfinite(v).sum(axis=1),
        },
        index=df.index,
    )
    stats["range"] = stats["max"] - stats["min"]
    out = pd.concat([stats[["default", "mean", "min", "max", "range", "n"]], df], axis=1)
    out.index.name = "figure"
    return out


def _markdown(table: pd.DataFrame, variants: list[str], default: str) -> str:
    cols = ["default", "mean", "min", "max", "range"]
    head = (
        f"| figure | {default} (default) | mean | min | max | range | "
        + " | ".join(variants)
        + " |"
    )
    lines = [head, "|---" + "|--:" * (len(cols) + len(variants)) + "|"]
    for name, r in table.iterrows():
        cells = [f"{r[c]:.4g}" if np.isfinite(r[c]) else "–" for c in cols + variants]
        lines.append(f"| {name.replace('|', chr(92) + '|')} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def spread_figure(table: pd.DataFrame, variants: list[str], path) -> None:
    """Each variant's force NRMSE (left) and sim-to-real coverage (right) per figure,
    the range as a bar."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    nrmse = table[table.index.str.endswith("NRMSE %")]
    cov = table[table.index.str.endswith("coverage %")]
    rows = max(len(nrmse), len(cov) + 1)
    # the coverage panel as tall as its rows (one row each, as the NRMSE panel's)
    fig, axes = plt.subplot_mosaic(
        [["nrmse", "cov"], ["nrmse", "."]],
        figsize=(13, 0.2 * rows + 1.6),
        width_ratios=[3, 1],
        height_ratios=[len(cov) + 1, rows - len(cov) - 1],
    )
    for key, t, label in (
        ("nrmse", nrmse, "force NRMSE (% of the largest force)"),
        ("cov", cov, "inside the interval (%)"),
    ):
        ax = axes[key]
        y = np.arange(len(t))
        ax.hlines(y, t["min"], t["max"], color="0.6", lw=3, zorder=1)
        for j, v in enumerate(variants):
            ax.plot(t[v], y, "o", ms=3.5, color=f"C{j % 10}", label=v, zorder=2)
        ax.set_yticks(y, t.index, fontsize=5.5)
        ax.set_ylim(len(t) - 0.5, -0.5)
        ax.set_xlabel(label, fontsize=8)
        ax.tick_params(axis="x", labelsize=7)
        ax.grid(axis="x", lw=0.3)
    axes["nrmse"].set_xscale("log")
    axes["cov"].legend(fontsize=6, loc="lower left")
    fig.suptitle(
        "Spread over training seeds and numeric types (sim-to-real on the EMULATED lab takes)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def variant_runs(histories: dict[str, dict]) -> dict[str, dict]:
    """Where and how a variant's models trained (model -> ``precision``, ``device``,
    ``cpu``), from their ``history.json``: a figure is worth saying which machine gave it."""
    return {
        m: {k: h.get(k) for k in ("precision", "device", "cpu")}
        for m, h in sorted(histories.items())
    }


def _figures_json(table: pd.DataFrame, variants: list[str]) -> dict:
    """:func:`spread_table`'s rows as JSON: figure -> default, mean, min, max, range and
    each variant's value (None where missing)."""
    return {
        name: {
            c: (None if not np.isfinite(r[c]) else float(r[c]))
            for c in ["default", "mean", "min", "max", "range"] + variants
        }
        for name, r in table.iterrows()
    }


def write_spread(
    figures: dict[str, dict[str, float]],
    default: str,
    out: dict,
    runs: dict[str, dict] | None = None,
) -> pd.DataFrame:
    """``out``: paths ``json``, ``csv``, ``table`` (Markdown) and ``figure``; ``runs``:
    variant -> :func:`variant_runs` (kept in the JSON)."""
    variants = list(figures)
    table = spread_table(figures, default)
    table.to_csv(out["csv"], float_format="%.6g")
    Path(out["table"]).write_text(_markdown(table, variants, default))
    summary = {
        "variants": variants,
        "default": default,
        "runs": runs or {},
        "figures": _figures_json(table, variants),
    }
    Path(out["json"]).write_text(json.dumps(summary, indent=1))
    spread_figure(table, variants, out["figure"])
    return table


def write_spread_rigs(summaries: dict[str, dict], default: str, out: dict) -> dict:
    """Sim-to-real on the emulated rigs over the variants (``summaries``: variant -> its
    rigs' ``summary.json``, whose ``max_nrmse_pct`` is the target): ``out`` paths
    ``json`` (the figures as in ``write_spread`` and :func:`rig_acceptance`), ``csv``,
    ``table`` (Markdown) and ``figure``."""
    targets = {float(s["max_nrmse_pct"]) for s in summaries.values()}
    if len(targets) != 1:
        raise ValueError(
            f"the variants' rigs were judged against different targets: {sorted(targets)}"
        )
    max_nrmse_pct = targets.pop()
    figures = {v: rig_figures(s) for v, s in summaries.items()}
    variants = list(figures)
    table = spread_table(figures, default)
    table.to_csv(out["csv"], float_format="%.6g")
    summary = {
        "emulated": True,
        "variants": variants,
        "default": default,
        "figures": _figures_json(table, variants),
    }
    summary["acceptance"] = rig_acceptance(summary, max_nrmse_pct)
    Path(out["table"]).write_text(
        "# Sim-to-real on the emulated rigs, over training seeds and numeric types\n\n"
        "Every rig is emulated (finray.emulator.rigs): `default` is config `lab:`, the others are "
        "drawn from `lab.rigs`; each variant is the camera model trained again "
        "(evaluate.spread).\n\n"
        + rigs_markdown(summary["acceptance"])
        + "\n"
        + _markdown(table, variants, default)
    )
    Path(out["json"]).write_text(json.dumps(summary, indent=1))
    rigs_spread_figure(summary["acceptance"], path=out["figure"])
    return summary


def rigs_spread_figure(acc: dict, path) -> None:
    """Per rig the NRMSE against the context count: the mean over the variants as a line,
    their range as a band; the pooled coverage's mean and range beside it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(8, 3.2))
    for j, (rig, r) in enumerate(acc["per_rig"].items()):
        k = np.arange(len(r["nrmse_pct_mean"]))
        style = {"lw": 2.2, "color": "k"} if rig == "default" else {"lw": 1.2, "color": f"C{j}"}
        axes[0].fill_between(
            k, r["nrmse_pct_min"], r["nrmse_pct_max"], color=style["color"], alpha=0.15
        )
        axes[0].plot(k, r["nrmse_pct_mean"], "o-", label=rig, **style)
    axes[0].axhline(acc["max_nrmse_pct"], color="grey", ls=":", lw=1)
    axes[0].set_ylabel("force NRMSE (%)")
    axes[0].set_ylim(bottom=0)
    cov = sorted(acc["coverage_pct_pooled"].items(), key=lambda kv: int(kv[0]))
    k = np.array([int(c) for c, _ in cov])
    mean = np.array([c["mean"] for _, c in cov])
    axes[1].errorbar(
        k,
        mean,
        yerr=[mean - [c["min"] for _, c in cov], [c["max"] for _, c in cov] - mean],
        fmt="o-",
        color="k",
        capsize=3,
        label="pooled over the rigs",
    )
    axes[1].axhspan(85, 95, color="grey", alpha=0.15)
    axes[1].set_ylabel("frames inside the 90 % interval (%)")
    axes[1].set_ylim(50, 100)
    for ax in axes:
        ax.set_xlabel("context objects")
        ax.set_xticks(k)
    axes[0].legend(fontsize=7, title="emulated rig", title_fontsize=7)
    fig.suptitle(
        f"Sim-to-real on EMULATED rigs over {len(acc['variants'])} trainings of the camera "
        "model (line: mean, band: range)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


#: The rows the manuscript quotes (:func:`manuscript_rows`): (label, figure names; one
#: name, or several of which each variant's worst is taken)
MODELS = ("camera", "plain", "occlusion", "pitch")


def _worst(figures: dict, names: list[str], variants: list[str]) -> dict | None:
    """Per variant the largest value over ``names`` (e.g. the worst pitch), and its
    mean, min, max, range and n over the variants."""
    per = {}
    for v in variants:
        vals = [figures[n][v] for n in names if figures[n].get(v) is not None]
        if vals:
            per[v] = max(vals)
    if not per:
        return None
    x = np.array(list(per.values()))
    return {
        **per,
        "mean": float(x.mean()),
        "min": float(x.min()),
        "max": float(x.max()),
        "range": float(x.max() - x.min()),
        "n": len(x),
    }


def manuscript_rows(spread: dict) -> list[dict]:
    """The headline figures over the variants, for the manuscript: per model its force
    NRMSE (%) and log-stress MSE on the held-out shapes, its NRMSE on the ring materials,
    its worst pitch of the viewpoint experiment (each variant's worst), the occlusion
    model unoccluded and at its worst level, the pitch model at 0 deg and at its worst
    pitch; sim-to-real per context count (NRMSE %, coverage %). Each row: ``label``,
    ``default`` (the default variant's value, None if it did not run), ``mean``,
    ``min``, ``max``, ``range``, ``n``."""
    figs, variants, default = spread["figures"], spread["variants"], spread["default"]
    rows = []

    def add(label, names):
        names = [n for n in names if n in figs]
        if not names:
            return
        w = _worst(figs, names, variants)
        if w:
            rows.append(
                {
                    "label": label,
                    "default": w.get(default),
                    **{k: w[k] for k in ("mean", "min", "max", "range", "n")},
                }
            )

    for m in MODELS:
        add(f"{m}: held-out shapes, force NRMSE %", [f"shape | all | {m} | force NRMSE %"])
        add(f"{m}: held-out shapes, log-stress MSE", [f"shape | all | {m} | log-stress MSE"])
        add(f"{m}: ring materials, force NRMSE %", [f"material | all | {m} | force NRMSE %"])
        add(
            f"{m}: viewpoint, worst pitch, force NRMSE %",
            [
                n
                for n in figs
                if n.startswith("viewpoint | ") and n.endswith(f" | {m} | force NRMSE %")
            ],
        )
    add(
        "occlusion: held-out shapes unoccluded, force NRMSE %",
        ["occlusion | none | occlusion | force NRMSE %"],
    )
    add(
        "occlusion: worst occlusion level, force NRMSE %",
        [
            n
            for n in figs
            if n.startswith("occlusion | ")
            and n.endswith(" | occlusion | force NRMSE %")
            and not n.startswith("occlusion | all |")
        ],
    )
    add(
        "pitch: the pitch scene at 0 deg (raster), force NRMSE %",
        ["pitch | 0 | pitch | force NRMSE %"],
    )
    add(
        "pitch: worst pitch (raster), force NRMSE %",
        [
            n
            for n in figs
            if n.startswith("pitch | ")
            and n.endswith(" | pitch | force NRMSE %")
            and not n.startswith("pitch | all |")
        ],
    )
    ks = sorted(
        {
            n.split(" | ")[1].split()[0]
            for n in figs
            if n.startswith("sim2real | ") and " context | " in n and "pooled" not in n
        },
        key=int,
    )
    for k in ks:
        add(f"sim-to-real, {k} context objects, NRMSE %", [f"sim2real | {k} context | NRMSE %"])
        add(
            f"sim-to-real, {k} context objects, coverage %",
            [f"sim2real | {k} context | coverage %"],
        )
    add(
        "sim-to-real, 1+ context objects pooled, coverage %",
        ["sim2real | 1+ context pooled | coverage %"],
    )
    return rows


def manuscript_spread(spread: dict) -> dict:
    """What the manuscript quotes of a spread study's ``summary.json``: its variants, the
    default, where each trained (``runs``; ``machines``: each device and numeric type
    once) and :func:`manuscript_rows`."""
    machines = sorted(
        {
            f"{r['device']}, {r['precision']}"
            for runs in spread["runs"].values()
            for r in runs.values()
        }
    )
    return {k: spread[k] for k in ("variants", "default", "runs")} | {
        "rows": manuscript_rows(spread),
        "machines": machines,
    }
