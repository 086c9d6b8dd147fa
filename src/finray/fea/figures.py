"""Figures and tables of the FEA stage (forces in N for the 20 mm finger, stress MPa)."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.colors import LogNorm
from scipy.spatial import cKDTree

from ..geometry.surface import P2_SUBTRIANGLES
from .simulate import boundary_loops


def _load(results, summaries):
    out = []
    for r, s in zip(results, summaries):
        with np.load(r) as f:
            d = {k: f[k] for k in ("displacement_mm", "fx_N", "n_pairs_self")}
        d.update(json.loads(Path(s).read_text()))
        d["path"] = r
        out.append(d)
    return out


def scene_table(summaries, out_csv) -> pd.DataFrame:
    """One row per scene: convergence checks, wall time, Newton iterations, contact, peak
    stress."""
    rows = []
    for s in summaries:
        d = json.loads(Path(s).read_text())
        rows.append(
            {
                k: d.get(k)
                for k in (
                    "scene",
                    "object",
                    "material",
                    "height_mm",
                    "split",
                    "converged",
                    "wall_time_s",
                    "n_steps",
                    "newton_iterations",
                    "fx_final_N",
                    "fy_final_N",
                    "max_von_mises_MPa",
                    "min_gap_mm",
                    "self_contact_max_pairs",
                    "self_contact_first_mm",
                    "residual_tol",
                    "residual_final_rel",
                    "residual_max_rel",
                    "equilibrium_tol",
                    "equilibrium_max_rel_error",
                    "line_search_failures",
                    "gradient_fallbacks",
                )
            }
        )
    df = pd.DataFrame(rows)
    df.to_csv(out_csv, index=False)
    return df


def force_displacement_figure(results, summaries, pdf, png=None) -> None:
    """Fx against travel, one panel per contact height; dots: first self-contact."""
    data = _load(results, summaries)
    heights = sorted({d["height_mm"] for d in data})
    fig, axes = plt.subplots(
        1, len(heights), figsize=(4.2 * len(heights), 4.2), squeeze=False, sharey=True
    )
    styles = {"train": "-", "shape": "--", "material": ":"}
    names = sorted({(d["object"], d["material"]) for d in data})
    cmap = plt.get_cmap("tab20")
    colours = {n: cmap(i % 20) for i, n in enumerate(names)}
    for ax, h in zip(axes[0], heights):
        for d in (d for d in data if d["height_mm"] == h):
            key = (d["object"], d["material"])
            label = d["object"] if d["material"] == "steel" else f"{d['object']} ({d['material']})"
            ax.plot(
                d["displacement_mm"],
                d["fx_N"],
                styles.get(d["split"], "-"),
                color=colours[key],
                lw=1.1,
                label=label,
            )
            touching = np.flatnonzero(d["n_pairs_self"] > 0)
            if len(touching):
                k = touching[0]
                ax.plot(d["displacement_mm"][k], d["fx_N"][k], "o", color=colours[key], ms=4)
        ax.set_title(f"contact height {h:g} mm", fontsize=9)
        ax.set_xlabel("object travel (mm)")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("contact force $F_x$ (N, 20 mm finger)")
    handles, labels = axes[0, -1].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center right", fontsize=6, frameon=False)
    fig.text(
        0.01,
        0.01,
        "solid: training objects, dashed: held-out shapes, dotted: ring "
        "materials; dots: first contact between the finger's own surfaces (ribs jamming)",
        fontsize=7,
    )
    fig.tight_layout(rect=(0, 0.04, 0.82, 1))
    fig.savefig(pdf)
    if png:
        fig.savefig(png, dpi=130)
    plt.close(fig)


def self_contact_points(
    points, boundary_edges, radius_mm: float = 0.05, neighbour_mm: float = 1.0
) -> np.ndarray:
    """Boundary nodes closer than ``radius_mm`` to a node of another surface (a node
    more than ``neighbour_mm`` away along the boundary, or on another loop)."""
    nodes, loop_of, arc = [], [], []
    for k, loop in enumerate(boundary_loops(boundary_edges)):
        e = boundary_edges[loop]
        seq = np.column_stack([e[:, 0], e[:, 2]]).ravel() if (e[:, 2] >= 0).all() else e[:, 0]
        p = points[seq]
        s = np.r_[0, np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))]
        nodes.append(seq)
        loop_of.append(np.full(len(seq), k))
        arc.append(s)
    nodes, loop_of, arc = map(np.concatenate, (nodes, loop_of, arc))
    pairs = cKDTree(points[nodes]).query_pairs(radius_mm, output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros((0, 2))
    i, j = pairs.T
    far = (loop_of[i] != loop_of[j]) | (np.abs(arc[i] - arc[j]) > neighbour_mm)
    hit = np.unique(np.r_[i[far], j[far]])
    return points[nodes[hit]]


def jamming_figure(results, summaries, png, prefer=("circle_d20", "steel")) -> None:
    """The final frame of a scene with self-contact: stress and the touching surfaces."""
    data = _load(results, summaries)
    jammed = [d for d in data if d["n_pairs_self"].max() > 0]
    pick = next((d for d in jammed if (d["object"], d["material"]) == prefer), None)
    pick = pick or (max(jammed, key=lambda d: d["n_pairs_self"].max()) if jammed else data[0])
    with np.load(pick["path"]) as f:
        pts = f["points"] + f["u_mm"][-1]
        tri = f["triangles"]
        vm = f["von_mises_MPa"][-1]
        obj = f["object_points_mm"][-1]
        oe = f["object_edges"]
        be = f["boundary_edges"]
        bt = f["boundary_tags"] if "boundary_tags" in f else np.zeros(len(be), int)
    sub = tri[:, P2_SUBTRIANGLES].reshape(-1, 3) if tri.shape[1] == 6 else tri
    fig, ax = plt.subplots(figsize=(5, 8))
    vmin = max(float(np.percentile(vm, 5)), 1e-4)
    tpc = ax.tripcolor(
        pts[:, 0],
        pts[:, 1],
        sub,
        np.maximum(vm, vmin),
        shading="gouraud",
        norm=LogNorm(vmin=vmin, vmax=float(vm.max())),
        cmap="inferno",
    )
    fig.colorbar(tpc, ax=ax, label="von Mises stress (MPa)", shrink=0.6)
    for a, b in oe:
        ax.plot(obj[[a, b], 0], obj[[a, b], 1], color="tab:blue", lw=0.8)
    contact = self_contact_points(pts, be[bt != 1] if bt.any() else be)
    if len(contact):
        ax.plot(
            contact[:, 0],
            contact[:, 1],
            "o",
            ms=3,
            mfc="none",
            mec="cyan",
            label="self-contact (ribs jamming)",
        )
        ax.legend(loc="upper left", fontsize=7)
    ax.set_aspect("equal")
    ax.set_title(
        f"{pick['object']} ({pick['material']}) at {pick['height_mm']:g} mm, "
        f"travel {pick['displacement_mm'][-1]:.1f} mm, F = {pick['fx_N'][-1]:.2f} N",
        fontsize=8,
    )
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    fig.tight_layout()
    fig.savefig(png, dpi=150)
    plt.close(fig)
