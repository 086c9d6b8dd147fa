"""Metrics against hand-computed values."""

import numpy as np
import pytest

from finray.evaluate.metrics import force_metrics, force_vector_metrics, stress_metrics


def test_force_metrics_by_hand():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    p = np.array([0.0, 1.0, 2.0, 5.0])
    m = force_metrics(t, p)
    assert m["mse_N2"] == pytest.approx(1.0)
    assert m["rmse_N"] == pytest.approx(1.0)
    assert m["nrmse_pct"] == pytest.approx(100 / 3)
    assert m["r2"] == pytest.approx(1 - 4 / 5)
    assert force_metrics(t, t)["r2"] == 1.0


def test_force_metrics_bad_input():
    with pytest.raises(ValueError):
        force_metrics([1, 2], [1])


def test_force_vector_metrics_of_fy_and_the_magnitude():
    fx, fy = np.array([3.0, 4.0, 0.0]), np.array([-4.0, -3.0, 0.0])
    exact = force_vector_metrics(fx, fy, fx, fy)
    assert exact["fy_mse_N2"] == 0.0 and exact["mag_mse_N2"] == 0.0
    assert exact["fy_max_true_N"] == 4.0 and exact["mag_max_true_N"] == 5.0  # |(3, -4)| = 5
    # fy off by 0.3 N on the first frame: fy MSE 0.03 N^2; magnitude |(3, -4.3)| - 5
    out = force_vector_metrics(fx, fy, fx, fy + np.array([-0.3, 0.0, 0.0]))
    assert out["fy_mse_N2"] == pytest.approx(0.09 / 3)
    assert out["mag_rmse_N"] == pytest.approx(abs(np.hypot(3.0, 4.3) - 5.0) / np.sqrt(3))
    assert out["fy_nrmse_pct"] == pytest.approx(100 * np.sqrt(0.03) / 4.0)


def test_stress_metrics_mask_and_ssim():
    rng = np.random.default_rng(0)
    t = rng.random((2, 32, 16))
    mask = np.zeros_like(t, bool)
    mask[:, 8:24, 4:12] = True
    p = t.copy()
    p[~mask] += 5.0  # errors outside the mask do not count
    out = stress_metrics(t, p, mask)
    assert out["stress_mse_log"] == 0.0
    assert stress_metrics(t, t, mask)["ssim"] == pytest.approx(1.0)
    p2 = t + 0.1 * mask
    assert stress_metrics(t, p2, mask)["stress_mse_log"] == pytest.approx(0.01)


def test_contact_metrics_by_hand():
    """Only frames with a true height and |fx| above the threshold count."""
    from finray.evaluate.metrics import contact_metrics

    true = [10.0, 20.0, np.nan, 40.0, 50.0]
    pred = [13.0, 16.0, 99.0, 40.0, 0.0]
    fx = [1.0, -2.0, 3.0, 0.5, 0.1]  # 0.5 is not above 0.5
    m = contact_metrics(true, pred, fx)
    assert m["n"] == 2
    assert m["rmse_mm"] == pytest.approx(np.sqrt((9 + 16) / 2))
    assert m["mae_mm"] == pytest.approx(3.5)
    assert contact_metrics(true, pred, fx, min_force_N=0.05)["n"] == 4
    empty = contact_metrics([np.nan], [1.0], [2.0])
    assert empty["n"] == 0 and np.isnan(empty["rmse_mm"])
    with pytest.raises(ValueError, match="one height and one force per frame"):
        contact_metrics([1.0, 2.0], [1.0], [1.0, 1.0])
