"""The FEA studies' helpers: cost/accuracy (finray.benchmarks.fea_pareto) and robustness (fea_stability)."""

import numpy as np
import pandas as pd
import pytest

from finray.benchmarks.fea_pareto import converged_estimate, richardson, write_pareto
from finray.fea.simulate import SimulationError


@pytest.mark.parametrize("p", [1.0, 2.0, 3.5])
def test_richardson_recovers_limit_and_order(p):
    h = np.array([1.0, 0.5, 0.35])
    f = 8.0 + 0.3 * h**p
    f0, order = richardson(h, f)
    assert f0 == pytest.approx(8.0, abs=1e-9)
    assert order == pytest.approx(p, abs=1e-6)


def test_richardson_refuses_non_monotone_data():
    f0, order = richardson([1.0, 0.5, 0.25], [8.1, 8.0, 8.05])
    assert f0 == 8.05 and np.isnan(order)


def _study_rows():
    # Fx = 8 + 0.2 h^2 + 4 c^2 (mesh h, chord c): the converged value is 8
    rows = [
        ("default", 1.0, 0.1),
        ("mesh", 0.5, 0.1),
        ("mesh", 0.35, 0.1),
        ("reference", 0.25, 0.1),
        ("arc chord", 1.0, 0.25),
        ("arc chord", 1.0, 0.05),
    ]
    return pd.DataFrame(
        [
            {
                "variant": f"{f} {h} {c}" if f != "default" else f,
                "factor": f,
                "mesh_size_mm": h,
                "arc_chord_mm": c,
                "order": 2,
                "n_nodes": 1,
                "wall_time_s": 1 / h**2,
                "cpu_time_s": 1 / h**2,
                "newton_iterations": 1,
                "fx_10mm_N": 8.0 + 0.2 * h**2 + 4.0 * c**2,
            }
            for f, h, c in rows
        ]
    )


def test_converged_estimate_adds_chord_correction():
    df = _study_rows()
    est = converged_estimate(df, 1.0, 0.1)
    assert est["sizes_mm"] == [0.25, 0.35, 0.5]
    assert est["order"] == pytest.approx(2.0, abs=1e-6)
    assert est["fx_N"] == pytest.approx(8.0, abs=1e-9)


def test_write_pareto_outputs(tmp_path):
    cfg = {
        "mesh": {"size_mm": 1.0, "arc_chord_mm": 0.1, "order": 2},
        "fea": {"max_step_mm": 0.5, "dhat_mm": 0.02},
    }
    df = write_pareto(_study_rows(), cfg, tmp_path / "p.csv", tmp_path / "p.png")
    assert (tmp_path / "p.png").stat().st_size > 0
    err = df.set_index("variant")["rel_error_pct"]
    assert err["default"] == pytest.approx(100 * (0.2 + 0.04) / 8.0)
    md = (tmp_path / "p.md").read_text()
    assert "Converged value** 8.0000 N" in md and "How the default was chosen" in md


@pytest.fixture(scope="module")
def smoke_cfg():
    from finray.config import load_config

    from helpers import ROOT

    return load_config(ROOT / "config" / "smoke.yaml")


def _raiser(exc):
    def run(cfg, cache=None, **scene):
        raise exc

    return run


INTERSECTS = "the object intersects the finger in the initial state"


def test_stability_suite_accepts_the_expected_refusal(smoke_cfg, tmp_path):
    from finray.benchmarks.fea_stability import Refusal, stability_suite

    cases = {"overlap": ({}, {}, Refusal(SimulationError, "intersects the finger"))}
    df = stability_suite(
        smoke_cfg,
        tmp_path / "s.csv",
        cases=cases,
        log=lambda *a: None,
        run=_raiser(SimulationError(INTERSECTS, step=0, cause="x")),
    )
    assert df["ok"].tolist() == [True] and not df["unexpected_error"].any()


@pytest.mark.parametrize(
    "exc", [TypeError("unsupported operand"), "SimulationError with another message"]
)
def test_stability_suite_fails_on_a_wrong_refusal(smoke_cfg, tmp_path, exc):
    """A refused case that raises the wrong error type, or the right type with the
    wrong message, fails the suite (after writing the table)."""
    from finray.benchmarks.fea_stability import Refusal, StabilityFailure, stability_suite

    if isinstance(exc, str):
        exc = SimulationError("load step 3 failed: line search failed", step=3, cause="ls")
    cases = {"overlap": ({}, {}, Refusal(SimulationError, "intersects the finger"))}
    with pytest.raises(StabilityFailure, match=r"unexpected error in overlap \(expected refuse"):
        stability_suite(
            smoke_cfg, tmp_path / "s.csv", cases=cases, log=lambda *a: None, run=_raiser(exc)
        )
    df = pd.read_csv(tmp_path / "s.csv")
    assert df["ok"].tolist() == [False] and df["unexpected_error"].tolist() == [True]


def test_stability_suite_converge_case(smoke_cfg, tmp_path):
    """A converge case stopping with a SimulationError is a finding (not ok, the suite
    goes on); any other exception there is a bug and fails the suite."""
    from finray.benchmarks.fea_stability import StabilityFailure, stability_suite

    cases = {"hard": ({}, {}, "converge")}
    df = stability_suite(
        smoke_cfg,
        tmp_path / "s.csv",
        cases=cases,
        log=lambda *a: None,
        run=_raiser(SimulationError("load step 2 failed", step=2, cause="c")),
    )
    assert df["ok"].tolist() == [False] and not df["unexpected_error"].any()
    with pytest.raises(StabilityFailure, match="hard"):
        stability_suite(
            smoke_cfg,
            tmp_path / "s.csv",
            cases=cases,
            log=lambda *a: None,
            run=_raiser(KeyError("fx")),
        )


def test_stability_cases_name_their_refusals():
    from finray.benchmarks.fea_stability import STABILITY_CASES, Refusal

    for case, (_, _, expected) in STABILITY_CASES.items():
        assert expected == "converge" or isinstance(expected, Refusal), case
    ov = STABILITY_CASES["overlap_0.2mm"][2]
    assert ov.matches(SimulationError(INTERSECTS))
    assert not ov.matches(TypeError(INTERSECTS))
