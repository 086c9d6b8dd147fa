"""Build and write the geometry of a config: finger mesh, surface, placed objects.

Files (all lengths in mm):

- ``finger.npz``: :class:`~finray.geometry.mesh.TriMesh` of the finger;
  ``finger.vtu`` the same for ParaView; ``finger.json`` parameters and mesh quality.
- ``finger_surface.ply``: watertight extruded surface (ParaView, MeshLab, Blender);
  ``finger_surface.npz`` the same with ``node_map`` to the 2D nodes.
- ``objects/<name>_h<height>.npz`` (+ ``.vtu``): the placed object.
"""

from __future__ import annotations

import json
from pathlib import Path

import meshio
import numpy as np

from .finger import FingerParams, mesh_finger
from .mesh import TriMesh
from .objects import object_geometry
from .surface import check_watertight, extrude


def finger_from_config(cfg: dict) -> FingerParams:
    return FingerParams.from_config(cfg["finger"])


def write_mesh(mesh: TriMesh, npz_path: str | Path) -> None:
    """Write ``mesh`` as ``.npz`` and, beside it, as ``.vtu`` with boundary tags."""
    npz_path = Path(npz_path)
    npz_path.parent.mkdir(parents=True, exist_ok=True)
    mesh.save(npz_path)
    mesh.to_meshio().write(npz_path.with_suffix(".vtu"))


def build_finger(cfg: dict, outdir: str | Path) -> dict:
    """Mesh the finger of ``cfg`` and write its files into ``outdir``; returns its summary."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    p = finger_from_config(cfg)
    m = cfg["mesh"]
    mesh = mesh_finger(p, m["size_mm"], m["min_angle_deg"], m["order"], m["arc_chord_mm"])
    write_mesh(mesh, outdir / "finger.npz")
    surf = extrude(mesh, p.extrusion_mm)
    topo = check_watertight(surf)
    if not topo["watertight"] or topo["signed_volume_mm3"] <= 0:
        raise RuntimeError(f"extruded finger surface is not closed and outward: {topo}")
    meshio.Mesh(surf.points, [("triangle", surf.faces.astype(np.int32))]).write(
        outdir / "finger_surface.ply"
    )
    np.savez_compressed(
        outdir / "finger_surface.npz", points=surf.points, faces=surf.faces, node_map=surf.node_map
    )
    summary = {
        "params": cfg["finger"],
        "mesh": m,
        **{k: v for k, v in mesh.meta.items() if k not in ("tag_ids",)},
        "surface": topo,
        "tag_ids": mesh.meta["tag_ids"],
    }
    (outdir / "finger.json").write_text(json.dumps(summary, indent=2))
    return summary


def build_object(
    cfg: dict, name: str, height_mm: float, out_npz: str | Path, deformable: bool
) -> TriMesh:
    """Place object ``name`` at ``height_mm`` and write it to ``out_npz`` (+ ``.vtu``)."""
    m = cfg["mesh"]
    obj = object_geometry(
        name,
        cfg["objects"][name],
        finger_from_config(cfg),
        height_mm,
        size_mm=m["size_mm"],
        deformable=deformable,
        gap_mm=cfg["placement"]["gap_mm"],
        min_angle_deg=m["min_angle_deg"],
    )
    write_mesh(obj, out_npz)
    return obj
