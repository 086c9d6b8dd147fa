"""The FEA robustness study (results/benchmarks/fea_stability.*): :func:`stability_suite`
runs hard scenes (sharp corners, long push, near-incompressible finger, objects just
above the clamped base and at the tip, soft deformable ring, friction extremes, initial
contact, extreme meshes) and
records whether each converges or stops with the expected error (type and message).

Units: lengths mm, forces N on the 20 mm finger, times s (wall clock, one thread).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import SimulationError, StabilityFailure
from .fea import FingerCache, any_nan, fx_at, markdown_table, min_gap, run_case, with_overrides
from .timing import Stopwatch

__all__ = ["stability_suite", "stability_cases", "STABILITY_CASES", "Refusal", "StabilityFailure"]


@dataclass(frozen=True)
class Refusal:
    """The clear stop a case expects: an ``error`` (type) whose message matches the
    regular expression ``match``; ``or_converge``: converging is correct too."""

    error: type = SimulationError
    match: str = ""
    or_converge: bool = False

    def matches(self, exc: BaseException) -> bool:
        return isinstance(exc, self.error) and re.search(self.match, str(exc)) is not None

    def __str__(self) -> str:
        return (
            "converge or " if self.or_converge else ""
        ) + f"refuse: {self.error.__name__} /{self.match}/"


#: case -> (config overrides, scene keywords of :func:`run_case`, expected outcome):
#: "converge", or a :class:`Refusal` (the expected error type and message).
STABILITY_CASES: dict[str, tuple[dict, dict, object]] = {
    "baseline": ({}, {}, "converge"),
    "sharp_corners_no_fillet": ({"finger.fillet_radius_mm": 0.0}, {}, "converge"),
    "push_15mm": ({"fea.push_mm": 15.0}, {}, "converge"),
    "finger_nu_0.499": ({"materials.@finger.poisson_ratio": 0.499}, {}, "converge"),
    "circle_d5_tip_h70": (
        {},
        {"spec": {"type": "circle", "diameter_mm": 5.0}, "height_mm": 70.0, "name": "circle_d5"},
        "converge",
    ),
    # the whole face: just above the clamped base (the push ends at fea.force_cap_N,
    # its frames kept: these three failed at 200-1000 N before the cap) and at the tip
    "circle_d10_base_h5.2": (
        {},
        {"spec": {"type": "circle", "diameter_mm": 10.0}, "height_mm": 5.2, "name": "circle_d10"},
        "converge",
    ),
    "square_s14_base_h8.7": (
        {},
        {
            "spec": {"type": "square", "side_mm": 14.0, "fillet_mm": 0.5},
            "height_mm": 8.7,
            "name": "square_s14",
        },
        "converge",
    ),
    "ellipse_16x9_base_h8.3": (
        {},
        {
            "spec": {"type": "ellipse", "width_mm": 16.0, "height_mm": 9.0, "angle_deg": 30.0},
            "height_mm": 8.3,
            "name": "ellipse_16x9",
        },
        "converge",
    ),
    "neoprene_ring_base_h8": (
        {},
        {
            "spec": {"type": "ring", "diameter_mm": 15.0, "wall_mm": 2.0},
            "material": "neoprene",
            "height_mm": 8.0,
            "name": "ring_d15",
        },
        "converge",
    ),
    "square_s10_a45_tip_h74": (
        {},
        {
            "spec": {"type": "square", "side_mm": 10.0, "angle_deg": 45.0, "fillet_mm": 0.5},
            "height_mm": 74.0,
            "name": "square_s10_a45",
        },
        "converge",
    ),
    "neoprene_ring_h20": (
        {},
        {
            "spec": {"type": "ring", "diameter_mm": 15.0, "wall_mm": 2.0},
            "material": "neoprene",
            "height_mm": 20.0,
            "name": "ring_d15",
        },
        "converge",
    ),
    "friction_0": ({"fea.friction": 0.0}, {}, "converge"),
    "friction_1": ({"fea.friction": 1.0}, {}, "converge"),
    "gap_0.001mm": ({"placement.gap_mm": 0.001}, {}, "converge"),
    "gap_0_touching": (
        {},
        {"gap_mm": 1e-9},
        Refusal(SimulationError, r"load step \d+|intersects", or_converge=True),
    ),
    "overlap_0.2mm": (
        {},
        {"shift_mm": 0.3},  # 0.1 mm gap - 0.3 mm shift
        Refusal(SimulationError, "intersects the finger in the initial state"),
    ),
    "mesh_2.0mm": ({"mesh.size_mm": 2.0}, {}, "converge"),
    "mesh_0.3mm": ({"mesh.size_mm": 0.3}, {}, "converge"),
}


def _resolve(overrides: dict, cfg: dict) -> dict:
    fm = cfg["finger"]["material"]
    return {k.replace("@finger", fm): v for k, v in overrides.items()}


def stability_cases(coarse_mm: float = 2.0, fine_mm: float = 0.3) -> dict:
    """:data:`STABILITY_CASES` with the very coarse and very fine meshes resized."""
    cases = {k: v for k, v in STABILITY_CASES.items() if k not in ("mesh_2.0mm", "mesh_0.3mm")}
    cases[f"mesh_{coarse_mm:g}mm"] = ({"mesh.size_mm": coarse_mm}, {}, "converge")
    cases[f"mesh_{fine_mm:g}mm"] = ({"mesh.size_mm": fine_mm}, {}, "converge")
    return cases


def stability_suite(
    cfg: dict,
    out_csv,
    out_md=None,
    cases: dict | None = None,
    *,
    mesh_size_mm: float = 0.75,
    log=print,
    run=None,
) -> pd.DataFrame:
    """Run the hard scenes of :data:`STABILITY_CASES` (steel Ø20 mm circle at 30 mm,
    mesh ``mesh_size_mm``, unless a case says otherwise); one row each.

    ``ok``: a "converge" case converged without NaN and with every gap > 0; a
    :class:`Refusal` case stopped with the expected error type and a message
    matching it (or converged, where allowed). A converge case that stops with a
    :class:`SimulationError` is a finding (``ok`` false, the suite goes on). Any
    other error (a refusal of the wrong type or message, or an exception other than
    :class:`SimulationError` in a converge case: a bug) fails the suite: the table
    is written, then :class:`StabilityFailure` names the cases. ``run``: the scene
    runner (default :func:`run_case`; tests inject errors through it).
    """
    cases = STABILITY_CASES if cases is None else cases
    run = run or run_case
    base = with_overrides(cfg, {"mesh.size_mm": mesh_size_mm, "fea.write_vtu": False})
    cache = FingerCache()
    rows = []
    clock = Stopwatch()  # the whole suite
    for case, (overrides, scene, expected) in cases.items():
        row = {
            "case": case,
            "converged": False,
            "stop_message": "",
            "failed_step": None,
            "wall_time_s": np.nan,
            "newton_iterations": None,
            "fx_10mm_N": np.nan,
            "min_gap_mm": np.nan,
            "any_nan": False,
            "line_search_failures": None,
            "gradient_fallbacks": None,
            "residual_max_rel": np.nan,
            "equilibrium_max_rel_error": np.nan,
            "stop": "",
            "push_reached_mm": np.nan,
            "max_force_N": np.nan,
            "expected": str(expected),
            "unexpected_error": False,
        }
        case_clock = Stopwatch()
        exc = None
        try:
            c = with_overrides(base, _resolve(overrides, base))
            r = run(c, cache=cache, **scene)
            res = r["result"]
            row.update(
                converged=True,
                wall_time_s=round(r["wall_time_s"], 3),
                newton_iterations=int(res.newton_iterations.sum()),
                fx_10mm_N=fx_at(res, 10.0),
                min_gap_mm=min_gap(res),
                any_nan=any_nan(res),
                line_search_failures=res.meta["line_search_failures"],
                gradient_fallbacks=res.meta["gradient_fallbacks"],
                stop=res.meta["stop"]["reason"],
                push_reached_mm=round(res.meta["stop"]["push_reached_mm"], 4),
                max_force_N=float(np.hypot(*res.force_N.T).max()),
                residual_max_rel=res.meta["residual_max_rel"],
                equilibrium_max_rel_error=float(res.equilibrium_rel_error[1:].max(initial=0.0)),
            )
        except SimulationError as e:
            exc = e
            row.update(
                stop_message=f"scene {case}: load step {e.step}: {e} [cause: {e.cause}]",
                failed_step=e.step,
                any_nan="non-finite" in f"{e} {e.cause}",
            )
        except Exception as e:
            exc = e
            row.update(stop_message=f"scene {case}: {type(e).__name__}: {e}")
        if not np.isfinite(row["wall_time_s"]):
            row["wall_time_s"] = round(case_clock.wall_s, 3)
        good_run = row["converged"] and not row["any_nan"] and row["min_gap_mm"] > 0
        if isinstance(expected, Refusal):
            clear_stop = exc is not None and expected.matches(exc) and not row["any_nan"]
            row["ok"] = bool(clear_stop or (expected.or_converge and good_run))
            row["unexpected_error"] = exc is not None and not expected.matches(exc)
        elif expected == "converge":
            row["ok"] = bool(good_run)
            row["unexpected_error"] = exc is not None and not isinstance(exc, SimulationError)
        else:
            raise ValueError(
                f"stability case {case}: expected must be 'converge' or a Refusal, not {expected!r}"
            )
        log(
            f"  {case:<24s} conv={row['converged']!s:5s} ok={row['ok']!s:5s} "
            f"{row['wall_time_s']:6.1f} s  Fx={row['fx_10mm_N']:.4f}  gap={row['min_gap_mm']:.2e}"
            + (f"  {row['stop_message']}" if row["stop_message"] else "")
        )
        rows.append(row)
    total = clock.wall_s
    log(f"suite wall time {total:.1f} s")
    df = pd.DataFrame(rows)
    out_csv = Path(out_csv)
    out_csv.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out_csv, index=False, float_format="%.6g")
    md = Path(out_md) if out_md else out_csv.with_suffix(".md")
    md.write_text(
        "# FEA stability suite\n\n"
        f"Steel circle Ø20 mm at contact height 30 mm, 10 mm push, P2 mesh {mesh_size_mm:g} mm, "
        "unless the case says otherwise. A push may end at fea.force_cap_N (column `stop`: "
        "force_cap, `push_reached_mm` how far; its frames kept): that converges too. "
        "A case is `ok` when it converges without NaN and "
        "with every gap (object and self contact, all frames) > 0, or, where a refusal is "
        "expected, stops with the expected error type and message (column `expected`). "
        f"{int(df['ok'].sum())}/{len(df)} ok; whole suite {total:.0f} s.\n\n"
        + markdown_table(df.drop(columns=["stop_message"]))
        + "\n\nStop messages:\n\n"
        + "".join(f"- `{r.case}`: {r.stop_message}\n" for r in df.itertuples() if r.stop_message)
        + ("" if (df["stop_message"] != "").any() else "- none\n")
    )
    bad = df[df["unexpected_error"]]
    if len(bad):
        raise StabilityFailure(
            "stability suite: unexpected error in "
            + "; ".join(
                f"{r.case} (expected {r.expected}): {r.stop_message}" for r in bad.itertuples()
            )
        )
    return df
