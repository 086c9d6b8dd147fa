"""The calibration of a print's time dependence: a synthetic take of a known Prony kernel
and softening is recovered, an elastic print's gives no relaxation, frame-by-frame
prediction (finray predict --calibration) follows the batch one, and the phases of a take."""

import json
from dataclasses import replace

import numpy as np
import pytest

from finray.emulator.motion import GripperMotion
from finray.sim2real.calibration import (
    PARAMS,
    CalibratedStream,
    CalibrationError,
    History,
    Priors,
    coverage,
    fit_calibration,
    predictive,
    read_calibration,
    time_point_fit,
)
from finray.sim2real.phases import take_phases
from finray.viscoelastic import relax

TRUE = {"relax": 0.2, "tau_s": 0.8, "softening": 0.15}
FPS = 30.0


def takes(law: dict | None, seed: int):
    """Three takes of the paper's motion at 5, 12 and 20 N: the network's elastic force
    mu (its error growing with the force), its spread s, the sensor's log y of a print
    of ``law`` (None: elastic), and the frames' history."""
    rng = np.random.default_rng(seed)
    m = GripperMotion(push_mm=1.0, speed_mm_s=1.0, hold_s=1.0, starts_s=(1.0, 5.5), duration_s=10.0)
    t = np.arange(0, 10.0, 1 / FPS)
    fe = np.concatenate([a * m.push(t) ** 1.5 for a in (5.0, 12.0, 20.0)])
    tt, seg = np.tile(t, 3), np.repeat([0, 1, 2], len(t))
    s = 0.02 + 0.02 * fe * rng.uniform(0.5, 1.5, len(fe))
    mu = fe + s * rng.standard_normal(len(fe))
    f = (
        fe
        if law is None
        else relax(tt, fe, [[law["relax"]]], [[law["tau_s"]]], [law["softening"]], seg)[0]
    )
    return mu, s, f + 0.03 * rng.standard_normal(len(fe)), History(tt, seg)


def calibrate(mu, s, y, history):
    priors = Priors()
    point = time_point_fit(mu, y, history, priors)
    h = replace(
        history, base_N=point["rest_N"], start=(point["relax"], point["tau_s"], point["softening"])
    )
    return fit_calibration(mu, s, y, priors, log=lambda m: None, history=h), h


@pytest.fixture(scope="module")
def fitted():
    mu, s, y, history = takes(TRUE, 0)
    cal, h = calibrate(mu, s, y, history)
    return cal, h, (mu, s, y)


def test_recovers_a_known_relaxation_and_softening(fitted):
    """The kernel and the softening within stated tolerances (relax and softening +-0.03,
    tau +-15 %), the chain converged, and the intervals cover ~90 % of new takes' frames."""
    cal, h, _ = fitted
    q = cal["summary"]
    assert q["relax"]["median"] == pytest.approx(TRUE["relax"], abs=0.03)
    assert q["tau_s"]["median"] == pytest.approx(TRUE["tau_s"], rel=0.15)
    assert q["softening"]["median"] == pytest.approx(TRUE["softening"], abs=0.03)
    assert cal["diagnostics"]["ok"] and set(cal["diagnostics"]["tau_steps"]) == set(PARAMS[2:])
    mu, s, y, history = takes(TRUE, 1)
    band = predictive(cal, mu, s, 0.9, history=history)
    assert 0.85 <= coverage(y, band) <= 0.95
    # read static, the same frames' intervals miss the relaxed ones
    assert coverage(y, predictive(cal, mu, s, 0.9)) < 0.8


def test_an_elastic_print_gives_no_relaxation():
    mu, s, y, history = takes(None, 2)
    cal, _ = calibrate(mu, s, y, history)
    q = cal["summary"]
    assert q["relax"]["q95"] < 0.03 and q["softening"]["q95"] < 0.03


def test_frame_by_frame_follows_the_batch_prediction(fitted, tmp_path):
    """finray predict applies the calibration causally, one frame at a time: its medians
    are the batch ones (to the posterior draws' noise); a frame time not after the last
    starts a new history, as a new video."""
    cal, h, (mu, s, y) = fitted
    path = tmp_path / "calibration.json"
    path.write_text(json.dumps(cal))
    cal = read_calibration(path)
    n = 300  # the first take
    batch = predictive(cal, mu[:n], s[:n], 0.9, history=History(h.t_s[:n], h.segments[:n]))
    stream = CalibratedStream(cal)
    med = np.array([stream.step(t, m, v)["median"] for t, m, v in zip(h.t_s[:n], mu[:n], s[:n])])
    assert np.abs(med - batch["median"]).max() < 0.05
    again = [stream.step(t, m, v)["median"] for t, m, v in zip(h.t_s[:n], mu[:n], s[:n])]
    assert np.abs(np.array(again) - batch["median"]).max() < 0.05


def test_a_static_calibration_reads_as_before(tmp_path):
    """A calibration of the static model's six parameters (written before the print's
    law) reads with the law elastic; a law out of its range is refused in one line."""
    rng = np.random.default_rng(3)
    cal = {"posterior": {"samples": (rng.normal(0, 0.01, (50, 6)) + [1, 0, -2, -3, 0, 3]).tolist()}}
    path = tmp_path / "old.json"
    path.write_text(json.dumps(cal))
    stream = CalibratedStream(read_calibration(path))
    assert not stream.timed
    assert stream.step(0.0, 2.0, 0.01)["median"] == pytest.approx(2.0, abs=0.05)
    bad = np.column_stack([np.asarray(cal["posterior"]["samples"]), np.full((50, 3), [1.2, 0, 0])])
    path.write_text(json.dumps({"posterior": {"samples": bad.tolist()}}))
    with pytest.raises(CalibrationError, match="relax and softening"):
        read_calibration(path)


def test_history_needs_each_take_in_time_order():
    with pytest.raises(CalibrationError, match="not increasing"):
        History(np.array([0.0, 0.2, 0.1]), np.array(["a", "a", "a"]))
    History(np.array([0.0, 0.2, 0.1]), np.array(["a", "a", "b"]))  # a new take starts again


def test_the_phases_of_a_take():
    m = GripperMotion(
        push_mm=10.0, speed_mm_s=10.0, hold_s=1.0, starts_s=(1.0, 5.5), duration_s=10.0
    )
    t = np.arange(0, 10.0, 1 / FPS)
    ph = take_phases(m.push(t))

    def at(s):
        return ph[int(round(s * FPS))]

    assert [at(s) for s in (0.5, 1.5, 2.5, 3.5, 4.5, 6.0, 7.0, 9.5)] == [
        "rest",
        "loading",
        "hold",
        "unloading",
        "rest",
        "second cycle",
        "second cycle",
        "rest",
    ]
