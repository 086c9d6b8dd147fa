"""The convergence helpers of the FEA cost/accuracy study (finray.fea.studies)."""
import numpy as np
import pandas as pd
import pytest

from finray.fea.studies import converged_estimate, pareto_front, richardson


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


def test_converged_estimate_adds_chord_correction():
    # Fx = 8 + 0.2 h^2 + 4 c^2 (mesh h, chord c): the estimate must give 8
    def fx(h, c):
        return 8.0 + 0.2 * h**2 + 4.0 * c**2

    rows = [("default", 1.0, 0.1), ("mesh", 0.5, 0.1), ("mesh", 0.35, 0.1),
            ("reference", 0.25, 0.1), ("arc chord", 1.0, 0.25), ("arc chord", 1.0, 0.05)]
    df = pd.DataFrame([{"factor": f, "mesh_size_mm": h, "arc_chord_mm": c, "order": 2,
                        "fx_10mm_N": fx(h, c)} for f, h, c in rows])
    est = converged_estimate(df, 1.0, 0.1)
    assert est["sizes_mm"] == [0.25, 0.35, 0.5]
    assert est["order"] == pytest.approx(2.0, abs=1e-6)
    assert est["fx_N"] == pytest.approx(8.0, abs=1e-9)


def test_pareto_front():
    assert pareto_front([1, 2, 3, 4], [5, 6, 1, 0.5]).tolist() == [0, 2, 3]
