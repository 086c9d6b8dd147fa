"""The FEA sweep over the whole face (results/benchmarks/fea_sweep/): seeded random
steel scenes (circles, squares at any angle, ellipses, polygons) at contact heights
drawn uniformly from the lowest the geometry allows (the object's lowest point on the
clamped base, y = 0) to ``height_max_mm``, each run as the workflow runs a scene.

:func:`draw_scenes` draws them (scene ``i`` from its own stream ``(seed, i)``, so the
first scenes are the same whatever ``count``), :func:`run_scenes` runs a batch and
:func:`sweep_summary` tells the outcomes (complete, stopped at ``fea.force_cap_N`` with
its frames kept, failed with the cause), the CPU time per scene and per 10 mm height
band and the largest force per band.

Units: lengths mm, forces N on the extruded finger, times s (CPU: the process's).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import SimulationError
from ..fea.scene import material_law, scene_object, simulation_options
from ..fea.simulate import simulate
from ..geometry.finger import FingerParams
from ..geometry.objects import object_geometry, object_shape
from .fea import FingerCache, markdown_table
from .timing import Stopwatch

__all__ = ["KINDS", "draw_scenes", "lowest_height_mm", "run_scenes", "sweep_summary"]

#: the shapes drawn, in equal shares
KINDS = ("circle", "square", "ellipse", "polygon")
#: mm: the heights' bands of the summary
BAND_MM = 10.0


def lowest_height_mm(spec: dict, size_mm: float) -> float:
    """Lowest contact height (mm) at which ``spec`` stays above the clamped base (its
    lowest point at y = 0, as :func:`~finray.geometry.objects.place_object` allows)."""
    return float(-object_shape(spec, size_mm).bounds[1])


def _spec(kind: str, rng: np.random.Generator, r: dict) -> dict:
    if kind == "circle":
        return {
            "type": "circle",
            "diameter_mm": round(float(rng.uniform(*r["circle_diameter_mm"])), 3),
        }
    if kind == "square":
        return {
            "type": "square",
            "side_mm": round(float(rng.uniform(*r["square_side_mm"])), 3),
            "angle_deg": round(float(rng.uniform(0.0, 90.0)), 2),
            "fillet_mm": 0.5,
        }
    if kind == "ellipse":
        w, h = rng.uniform(*r["ellipse_axis_mm"], size=2)
        return {
            "type": "ellipse",
            "width_mm": round(float(w), 3),
            "height_mm": round(float(h), 3),
            "angle_deg": round(float(rng.uniform(0.0, 180.0)), 2),
        }
    if kind == "polygon":  # star-shaped about the reference point, hence simple
        n = int(rng.integers(3, 8))
        # one vertex in each of n equal sectors, 20 % of a sector apart at least
        ang = 2 * np.pi * (np.arange(n) + rng.uniform(0.0, 0.8, n)) / n + rng.uniform(0, 2 * np.pi)
        rad = rng.uniform(*r["polygon_radius_mm"], size=n)
        pts = np.column_stack([rad * np.cos(ang), rad * np.sin(ang)])
        return {"type": "polygon", "vertices_mm": np.round(pts, 3).tolist(), "fillet_mm": 0.5}
    raise ValueError(f"unknown sweep shape {kind!r}: one of {', '.join(KINDS)}")


def draw_scenes(
    count: int, seed: int, ranges: dict, finger: FingerParams, size_mm: float
) -> list[dict]:
    """``count`` scenes ``{"scene", "kind", "spec", "height_mm", "height_min_mm"}``.

    ``ranges``: ``circle_diameter_mm``, ``square_side_mm``, ``ellipse_axis_mm``,
    ``polygon_radius_mm`` ([lo, hi] mm, uniform), ``height_max_mm`` (the top of the
    heights, below the finger's ``height_mm``). Squares at any angle (0-90 deg),
    ellipses at 0-180 deg, polygons of 3-7 vertices with 0.5 mm fillets.
    """
    if count < 1:
        raise ValueError(f"the sweep needs at least one scene, got count={count}")
    top = float(ranges["height_max_mm"])
    if not 0 < top < finger.height_mm:
        raise ValueError(f"height_max_mm {top} mm is outside the finger (0, {finger.height_mm}) mm")
    scenes = []
    for i in range(count):
        rng = np.random.default_rng([seed, i])
        kind = KINDS[int(rng.integers(len(KINDS)))]
        spec = _spec(kind, rng, ranges)
        lo = lowest_height_mm(spec, size_mm)
        if lo >= top:
            raise ValueError(
                f"sweep scene {i}: a {kind} reaching {lo:.1f} mm below its "
                f"reference does not fit below height_max_mm {top} mm"
            )
        # just above the lowest height: place_object refuses an object below y = 0
        h = float(rng.uniform(lo + 1e-3, top))
        scenes.append(
            {
                "scene": f"s{i:04d}",
                "kind": kind,
                "spec": spec,
                "height_mm": round(h, 4),
                "height_min_mm": round(lo, 4),
            }
        )
    return scenes


def run_scenes(cfg: dict, scenes: list[dict], material: str = "steel", log=print) -> pd.DataFrame:
    """Run each scene as the workflow's FEA job (``cfg``'s mesh, placement and
    solver); one row each: ``outcome`` ("complete", "force_cap" or "failed"),
    ``cause`` and ``message`` of a failure, ``push_reached_mm``, ``n_frames``,
    ``max_force_N`` (largest |F|), ``max_fx_N``, ``cpu_s`` (placing and solving)."""
    cache = FingerCache()
    finger, _ = cache.get(cfg)
    fp = FingerParams.from_config(cfg["finger"])
    m = cfg["mesh"]
    law = material_law(cfg, cfg["finger"]["material"])
    rows = []
    for sc in scenes:
        row = {k: sc[k] for k in ("scene", "kind", "height_mm", "height_min_mm")}
        row.update(
            spec=json.dumps(sc["spec"]),
            outcome="failed",
            cause="",
            message="",
            push_reached_mm=np.nan,
            n_frames=0,
            max_force_N=np.nan,
            max_fx_N=np.nan,
            newton_iterations=0,
            load_steps=0,
        )
        with Stopwatch() as t:
            try:
                obj = object_geometry(
                    sc["scene"],
                    sc["spec"],
                    fp,
                    sc["height_mm"],
                    m["size_mm"],
                    not cfg["materials"][material]["rigid"],
                    cfg["placement"]["gap_mm"],
                    m["min_angle_deg"],
                )
                res = simulate(
                    finger, scene_object(obj, material, cfg), law, simulation_options(cfg)
                )
                f = -res.force_N
                row.update(
                    outcome=res.meta["stop"]["reason"],
                    push_reached_mm=res.meta["stop"]["push_reached_mm"],
                    n_frames=len(f),
                    max_force_N=float(np.hypot(*f.T).max()),
                    max_fx_N=float(f[:, 0].max()),
                    newton_iterations=int(res.newton_iterations.sum()),
                    load_steps=int(res.load_steps[-1]),
                )
            except SimulationError as e:
                part = e.partial or {}
                fp_ = np.asarray(part.get("force_N", np.zeros((0, 2))))
                row.update(
                    cause=e.cause or "",
                    message=str(e).splitlines()[0],
                    n_frames=len(fp_),
                    max_force_N=float(np.hypot(*fp_.T).max()) if len(fp_) else np.nan,
                )
        row.update(cpu_s=round(t.cpu_s, 3), wall_s=round(t.wall_s, 3))
        log(
            f"{row['scene']} {row['kind']:<7s} h={row['height_mm']:6.2f} {row['outcome']:<9s} "
            f"{row['cpu_s']:6.1f} s CPU  |F|max={row['max_force_N']:.1f} N {row['message']}"
        )
        rows.append(row)
    return pd.DataFrame(rows)


def sweep_summary(df: pd.DataFrame, force_cap_N: float, machine: str = "") -> str:
    """Markdown: outcome counts (each failure with its cause), CPU time per scene
    (median and quartiles) and per 10 mm height band, the largest force per band."""
    n = len(df)
    counts = df["outcome"].value_counts()
    ok = int(counts.get("complete", 0) + counts.get("force_cap", 0))
    q = df["cpu_s"].quantile([0.25, 0.5, 0.75])
    band = (df["height_mm"] // BAND_MM * BAND_MM).astype(int)
    bands = df.assign(band=band.map(lambda b: f"{b}-{b + int(BAND_MM)}")).groupby(
        "band", sort=False
    )
    per_band = pd.DataFrame(
        {
            "scenes": bands.size(),
            "complete": bands["outcome"].apply(lambda s: int((s == "complete").sum())),
            "force_cap": bands["outcome"].apply(lambda s: int((s == "force_cap").sum())),
            "failed": bands["outcome"].apply(lambda s: int((s == "failed").sum())),
            "cpu_median_s": bands["cpu_s"].median(),
            "cpu_max_s": bands["cpu_s"].max(),
            "max_force_N": bands["max_force_N"].max(),
            "push_reached_min_mm": bands["push_reached_mm"].min(),
        }
    ).reset_index()
    per_band["_k"] = per_band["band"].map(lambda s: int(s.split("-")[0]))
    per_band = per_band.sort_values("_k").drop(columns="_k")
    failed = df[df["outcome"] == "failed"]
    lines = [
        "# FEA over the whole face: a seeded sweep of steel scenes\n",
        f"{n} scenes (circles, squares at any angle, ellipses, polygons), contact heights "
        "uniform from the lowest the geometry allows (the object's lowest point on the "
        f"clamped base) to the sweep's top; a push stops at fea.force_cap_N = {force_cap_N:g} N "
        "with its frames kept." + (f" Machine: {machine}." if machine else "") + "\n",
        f"**{ok}/{n} ({100 * ok / n:.1f} %) reach the end of the push or the force cap** "
        f"(complete {int(counts.get('complete', 0))}, force_cap "
        f"{int(counts.get('force_cap', 0))}, failed {int(counts.get('failed', 0))}).\n",
        f"CPU time per scene (placing and solving, one thread): median {q[0.5]:.1f} s, "
        f"quartiles {q[0.25]:.1f}-{q[0.75]:.1f} s, total {df['cpu_s'].sum():.0f} s.\n",
        "## Per 10 mm height band\n",
        markdown_table(per_band) + "\n",
        "## Failures\n",
    ]
    lines += [
        f"- `{r.scene}` ({r.kind}, h {r.height_mm:.2f} mm, {r.spec}): [{r.cause}] {r.message}"
        for r in failed.itertuples()
    ] or ["- none"]
    return "\n".join(lines) + "\n"


def write_summary(
    tables, out_md, force_cap_N: float, machine: str = "", out_csv=None
) -> pd.DataFrame:
    """Concatenate the batches' CSV ``tables``, write the summary (and the joined CSV)."""
    df = pd.concat([pd.read_csv(t, keep_default_na=True) for t in tables], ignore_index=True)
    df["cause"] = df["cause"].fillna("")
    df["message"] = df["message"].fillna("")
    df = df.sort_values("scene").reset_index(drop=True)
    if out_csv is not None:
        df.to_csv(out_csv, index=False, float_format="%.6g")
    Path(out_md).write_text(sweep_summary(df, force_cap_N, machine))
    return df
