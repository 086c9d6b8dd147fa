"""One scene of the FEA studies (results/benchmarks/), run from a config with overrides:
:func:`run_case` and what is read off it. The studies: :mod:`.fea_pareto` (cost against
accuracy) and :mod:`.fea_stability` (robustness).

Units: lengths mm, forces N on the 20 mm finger (Fx positive along the push, i.e.
the force the object applies to the finger), times s (wall clock, one thread).
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd

from ..config import validate_config
from ..fea.scene import material_law, scene_object, simulation_options
from ..fea.simulate import simulate
from ..geometry.finger import FingerParams, mesh_finger
from ..geometry.mesh import TriMesh
from ..geometry.objects import object_geometry
from .timing import Stopwatch
from ..schema import schema_default

__all__ = [
    "run_case",
    "study_config",
    "with_overrides",
    "fx_at",
    "min_gap",
    "any_nan",
    "markdown_table",
    "FingerCache",
    "CIRCLE_D20",
]

CIRCLE_D20 = {"type": "circle", "diameter_mm": 20.0}


def _set(cfg: dict, dotted: str, value) -> None:
    d = cfg
    *head, last = dotted.split(".")
    for k in head:
        d = d[k]
    d[last] = value


def study_config(fea: dict, mesh: dict, finger: dict, materials: dict, placement: dict) -> dict:
    """A config of the sections the studies read, with the studies' own object (the
    steel circle) so that it validates as a whole."""
    return {
        "fea": fea,
        "mesh": mesh,
        "finger": finger,
        "materials": materials,
        "placement": placement,
        "objects": {"circle_d20": CIRCLE_D20},
    }


def with_overrides(cfg: dict, overrides: dict | None, validate: bool = True) -> dict:
    """Copy of ``cfg`` with dotted-key ``overrides`` (e.g. ``{"mesh.size_mm": 0.5}``),
    validated again (a forbidden value raises :class:`~finray.config.ConfigError`)."""
    out = copy.deepcopy(cfg)
    for k, v in (overrides or {}).items():
        _set(out, k, v)
    return validate_config(out) if validate else out


def markdown_table(df: pd.DataFrame) -> str:
    """``df.to_markdown`` (needs ``tabulate``), else a plain pipe table."""
    try:
        return df.to_markdown(index=False, floatfmt=".4g")
    except ImportError:
        fmt = lambda v: f"{v:.4g}" if isinstance(v, float) else str(v)  # noqa: E731
        lines = ["| " + " | ".join(map(str, df.columns)) + " |", "|" + "---|" * len(df.columns)]
        lines += ["| " + " | ".join(fmt(v) for v in r) + " |" for r in df.itertuples(index=False)]
        return "\n".join(lines)


class FingerCache:
    """Finger meshes by (geometry, size, order): meshing a fine finger takes seconds."""

    def __init__(self):
        self._meshes: dict = {}

    def get(self, cfg: dict) -> tuple[TriMesh, float]:
        m = cfg["mesh"]
        key = (
            repr(sorted(cfg["finger"].items())),
            m["size_mm"],
            m["min_angle_deg"],
            m["order"],
            m["arc_chord_mm"],
        )
        if key not in self._meshes:
            with Stopwatch() as t:
                mesh = mesh_finger(
                    FingerParams.from_config(cfg["finger"]),
                    m["size_mm"],
                    m["min_angle_deg"],
                    m["order"],
                    m["arc_chord_mm"],
                )
            self._meshes[key] = (mesh, t.wall_s)
        return self._meshes[key]


def _place(
    cfg: dict,
    spec: dict,
    material: str,
    height_mm: float,
    name: str,
    shift_mm: float = 0.0,
    gap_mm: float | None = None,
    object_size_mm: float | None = None,
) -> TriMesh:
    deformable = not cfg["materials"][material]["rigid"]
    m = cfg["mesh"]
    obj = object_geometry(
        name,
        spec,
        FingerParams.from_config(cfg["finger"]),
        height_mm,
        size_mm=object_size_mm or m["size_mm"],
        deformable=deformable,
        gap_mm=cfg["placement"]["gap_mm"] if gap_mm is None else gap_mm,
        min_angle_deg=m["min_angle_deg"],
    )
    if shift_mm:
        obj.points = obj.points + np.array([shift_mm, 0.0])  # towards (into) the finger
    return obj


def run_case(
    cfg: dict,
    spec: dict = CIRCLE_D20,
    material: str = "steel",
    height_mm: float = 30.0,
    name: str = "circle_d20",
    cache: FingerCache | None = None,
    frame_step_mm=None,
    shift_mm: float = 0.0,
    gap_mm: float | None = None,
    object_size_mm: float | None = None,
) -> dict:
    """Mesh, place and simulate one scene of ``cfg``; returns the result and timings.

    The object is discretised at ``object_size_mm`` (default: the mesh size, as in
    the workflow: a rigid circle gets chords of about half of it).

    Raises whatever the geometry or the solver raise (the callers decide).
    """
    cache = cache or FingerCache()
    finger, t_mesh = cache.get(cfg)
    obj_mesh = _place(cfg, spec, material, height_mm, name, shift_mm, gap_mm, object_size_mm)
    obj = scene_object(obj_mesh, material, cfg)
    opts = simulation_options(cfg)
    if frame_step_mm is not None:
        opts.frame_step_mm = frame_step_mm
    with Stopwatch() as t:
        res = simulate(finger, obj, material_law(cfg, cfg["finger"]["material"]), opts)
    return {
        "result": res,
        "wall_time_s": t.wall_s,
        "cpu_time_s": t.cpu_s,
        "mesh_time_s": t_mesh,
        "n_nodes": len(finger.points),
        "n_dofs": res.meta["n_dofs"],
    }


def fx_at(res, push_mm: float = schema_default("fea.push_mm")) -> float:
    """Fx (N, on the finger, + along the push) at ``push_mm`` of prescribed push."""
    fx = -res.force_N[:, 0]
    if push_mm > res.target_mm[-1] + 1e-9:
        return float("nan")
    return float(np.interp(push_mm, res.target_mm, fx))


def min_gap(res) -> float:
    g = np.concatenate(
        [np.asarray(res.min_gap_object_mm, float), np.asarray(res.min_gap_self_mm, float)]
    )
    g = g[np.isfinite(g)]
    return float(g.min()) if len(g) else float("nan")


def any_nan(res) -> bool:
    arrays = [
        res.force_N,
        res.base_reaction_N,
        res.finger_displacement_mm,
        res.object_displacement_mm,
        res.displacement_mm,
    ]
    if res.finger_von_mises_MPa is not None:
        arrays.append(res.finger_von_mises_MPa)
    return not all(np.isfinite(a).all() for a in arrays)
