"""Figures of the geometry: the object gallery and one scene."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import LineCollection

from .mesh import BOUNDARY_TAGS, TriMesh

TAG_COLOURS = {
    "base": "black",
    "front": "tab:red",
    "back": "tab:blue",
    "tip": "tab:purple",
    "cavity": "tab:green",
    "object": "0.2",
    "object_inner": "0.5",
}
HEIGHT_COLOURS = ["tab:orange", "tab:cyan", "tab:pink", "tab:olive", "tab:brown"]


def draw_boundary(ax, mesh: TriMesh, colour=None, lw: float = 0.6, by_tag: bool = False) -> None:
    """Draw the boundary of a mesh (P2 edges through their mid node)."""
    e = mesh.boundary_edges
    if mesh.order == 2 and (e[:, 2] >= 0).all():
        segs = np.concatenate([mesh.points[e[:, [0, 2]]], mesh.points[e[:, [2, 1]]]])
        tags = np.concatenate([mesh.boundary_tags, mesh.boundary_tags])
    else:
        segs, tags = mesh.points[e[:, :2]], mesh.boundary_tags
    if by_tag:
        names = {v: k for k, v in BOUNDARY_TAGS.items()}
        colours = [TAG_COLOURS[names[t]] for t in tags]
    else:
        colours = colour
    ax.add_collection(LineCollection(segs, colors=colours, linewidths=lw))


def gallery(
    finger: TriMesh,
    objects: dict[str, list[TriMesh]],
    path_pdf: str | Path,
    path_png: str | Path | None = None,
    splits: dict[str, str] | None = None,
) -> None:
    """One panel per object: the finger and the object at every contact height."""
    names = list(objects)
    ncol = min(6, len(names))
    nrow = int(np.ceil(len(names) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(2.0 * ncol, 3.2 * nrow), squeeze=False)
    for ax in axes.ravel()[len(names) :]:
        ax.axis("off")
    heights = sorted({o.meta["height_mm"] for objs in objects.values() for o in objs})
    for ax, name in zip(axes.ravel(), names):
        draw_boundary(ax, finger, "0.55", lw=0.3)
        for o in objects[name]:
            c = HEIGHT_COLOURS[heights.index(o.meta["height_mm"]) % len(HEIGHT_COLOURS)]
            draw_boundary(ax, o, c, lw=0.8)
            ax.plot(*o.meta["reference_point_mm"], "+", color=c, ms=4)
        title = name if not splits else f"{name}\n({splits[name]})"
        ax.set_title(title, fontsize=7)
        ax.set_aspect("equal")
        ax.set_xlim(-32, finger.points[:, 0].max() + 2)
        ax.set_ylim(-2, finger.points[:, 1].max() + 2)
        ax.tick_params(labelsize=5)
    handles = [
        plt.Line2D(
            [], [], color=HEIGHT_COLOURS[i % len(HEIGHT_COLOURS)], label=f"contact height {h:g} mm"
        )
        for i, h in enumerate(heights)
    ]
    fig.legend(handles=handles, loc="lower center", ncol=len(heights), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    fig.savefig(path_pdf)
    if path_png:
        fig.savefig(path_png, dpi=150)
    plt.close(fig)


def scene_figure(finger: TriMesh, obj: TriMesh | None, path: str | Path) -> None:
    """Finger mesh with coloured boundary tags and an optional object."""
    fig, ax = plt.subplots(figsize=(4, 8))
    ax.triplot(
        finger.points[:, 0], finger.points[:, 1], finger.corner_triangles, lw=0.15, color="0.7"
    )
    draw_boundary(ax, finger, by_tag=True, lw=0.8)
    if obj is not None:
        if len(obj.triangles):
            ax.triplot(
                obj.points[:, 0], obj.points[:, 1], obj.corner_triangles, lw=0.15, color="0.7"
            )
        draw_boundary(ax, obj, by_tag=True, lw=0.8)
    handles = [plt.Line2D([], [], color=c, label=k) for k, c in TAG_COLOURS.items()]
    ax.legend(handles=handles, fontsize=6, loc="upper left")
    ax.set_aspect("equal")
    ax.autoscale()
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)
