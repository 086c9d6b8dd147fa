"""Load stepping (:func:`march`): the push from 0 to each frame's load factor.

Adaptive steps (halved on failure, doubled after easy steps, bounded by the frame
spacing), a predictor (the previous increment extrapolated, or the linear response to
the step's load with the last factorisation), and friction normal
forces/tangents lagged at the step start and re-lagged ``friction_lag_iterations``
times within the step's Newton solve, at each convergence (or first once its step
falls below ``friction_relag_dx``, off by default).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import SimulationError
from .newton import NewtonOptions, newton
from .problem import Model
from ..schema import schema_default


@dataclass
class StepOptions:
    initial_step: float = 0.05  # fraction of the load path
    max_step: float = 0.05
    min_step: float = 1e-4
    grow: float = 2.0
    easy_iterations: int = 6  # grow the step when Newton took at most this many
    max_retries: int = schema_default("fea.max_retries")  # step cuts in a row before giving up
    friction_lag_iterations: int = 0  # friction re-lags within each step's solve
    # mm: the first re-lag once Newton's step is this small (0: at convergence). 1e-3 saves
    # ~13 % of the factorisations but moved a steel scene's force by 6 % at a slip event
    friction_relag_dx: float = 0.0
    # "secant": the previous increment extrapolated; "tangent": the linear response to
    # the step's load change (driver target, applied forces) solved with Newton's last
    # factorisation, secant before any; "none": each step starts where the last ended.
    # Tangent took 14 % fewer factorisations on the steel scenes (the CCD cuts the
    # extrapolated rib contacts short once the ribs touch), but it changes which of
    # the near-equal equilibria some square objects end on: 4 of the 57 steel scenes
    # moved by 1-10 % of their largest Fx at late frames, so it is not the default
    predictor: str = "secant"
    max_driver_lag: float | None = 1e-3  # mm; a larger lag means the object is blocked
    # a converged step whose limit ratio (march's ``limit``) exceeds 1 + this is cut in
    # half and retried, so that a stop at the limit lands within this fraction of it
    limit_overshoot: float = 0.05


def march(
    model: Model,
    q: np.ndarray,
    targets,
    frames: np.ndarray,
    step_opts: StepOptions | None = None,
    newton_opts: NewtonOptions | None = None,
    on_frame=None,
    friction: bool = True,
    limit=None,
):
    """Advance the load factor s from its current 0 to each value in ``frames``.

    ``targets(s)`` gives the driver target (2,) at load factor s (also sets
    ``model.load = s`` for external forces). ``on_frame(k, s, q, info)`` is called
    at every frame with the Newton iterations and wall time since the previous one
    and ``residual_rel``, the residual of the solve that reached the frame
    (:meth:`Model.residual_norm`); a q it returns replaces the frame's state.
    ``limit(q)``, when given, is a physical limit's ratio (e.g. force / cap) at each
    converged step: the first step that reaches 1 ends the march there, its state
    recorded as a last frame (``info["stop"]`` True) at its own load factor; a step
    past ``1 + limit_overshoot`` is cut in half and retried first (down to
    ``min_step``). Raises :class:`SimulationError` naming the step and the cause on
    failure. Returns the final q.
    """
    so = step_opts or StepOptions()
    no = newton_opts or NewtonOptions()
    if so.predictor not in ("secant", "tangent", "none"):
        raise ValueError(f"unknown predictor {so.predictor!r}: use secant, tangent or none")
    s = 0.0
    ds = so.initial_step
    step = 0
    q_prev, s_prev = None, None
    iters_frame = 0
    residual = np.nan
    t_frame = time.perf_counter()
    for k, s_f in enumerate(frames):
        while s < s_f - 1e-12:
            s_new = min(s + ds, s_f)
            if s_f - s_new < 0.25 * ds:  # avoid a sliver step before the frame
                s_new = s_f
            retries = 0
            while True:
                step += 1
                model.load = s_new
                model.t_target = np.asarray(targets(s_new), float)
                U_start = model.U(q)
                model.U_step_start = U_start
                if model.contact is not None:
                    model.contact.update_friction(U_start if friction else None)
                q_init = None
                if so.predictor == "tangent":
                    q_init = _predict_tangent(model, q, s_new - s)
                if (
                    q_init is None
                    and so.predictor in ("tangent", "secant")
                    and q_prev is not None
                    and s > s_prev
                ):
                    q_init = _cut(model, q, (q - q_prev) * ((s_new - s) / (s - s_prev)))
                if q_init is None:
                    q_init = q
                relag = None
                if friction and model.contact is not None and model.contact.params.mu > 0:
                    relag = lambda q_: model.contact.update_friction(model.U(q_))  # noqa: E731
                res = newton(
                    model, q_init, no, relag, so.friction_lag_iterations, so.friction_relag_dx
                )
                iters = res.iterations
                iters_frame += iters
                if res.converged and model.has_driver and so.max_driver_lag is not None:
                    lag = float(np.abs(model.t(res.q) - model.t_target).max())
                    if lag > so.max_driver_lag:
                        raise SimulationError(
                            f"load step {step} (load factor {s:.5f} -> {s_new:.5f}): the "
                            f"driven object lags its prescribed position by {lag:.3g} mm; it "
                            f"is blocked (e.g. pressed against the clamped base)",
                            step=step,
                            load=s_new,
                            cause="object blocked",
                        )
                stop = False
                if res.converged and limit is not None:
                    ratio = limit(res.q)
                    stop = ratio >= 1.0
                    if ratio > 1.0 + so.limit_overshoot and (s_new - s) / 2 >= so.min_step:
                        # past the limit by more than the overshoot: a shorter step
                        ds = (s_new - s) / 2
                        s_new = s + ds
                        continue
                if res.converged:
                    break
                retries += 1
                if retries > so.max_retries or (s_new - s) / 2 < so.min_step:
                    raise SimulationError(
                        f"load step {step} (load factor {s:.5f} -> {s_new:.5f}) failed: "
                        f"{res.cause}",
                        step=step,
                        load=s_new,
                        cause=res.cause,
                    )
                ds = (s_new - s) / 2
                s_new = s + ds
            q_prev, s_prev = q, s
            q, s = res.q, s_new
            residual = res.residual
            if iters <= so.easy_iterations:
                ds = min(so.max_step, ds * so.grow)
            if stop:
                if on_frame is not None:
                    q_frame = on_frame(
                        k,
                        s,
                        q,
                        {
                            "newton_iterations": iters_frame,
                            "wall_time_s": time.perf_counter() - t_frame,
                            "steps": step,
                            "residual_rel": residual,
                            "stop": True,
                        },
                    )
                    q = q if q_frame is None else q_frame
                return q
        if on_frame is not None:
            q_frame = on_frame(
                k,
                s,
                q,
                {
                    "newton_iterations": iters_frame,
                    "wall_time_s": time.perf_counter() - t_frame,
                    "steps": step,
                    "residual_rel": residual,
                },
            )
            if q_frame is not None:  # e.g. polished to a tighter tolerance by the caller
                q = q_frame
        iters_frame = 0
        t_frame = time.perf_counter()
    return q


def _predict_tangent(model: Model, q, ds: float):
    """q moved by the linear response to the load change ``ds`` and the driver's new
    target (``model.load``, ``model.t_target`` already the step's), with the last
    factorisation: Newton's first step from the converged q, without a factorisation.
    Cut to a valid, collision-free fraction; None before any factorisation (or where
    no fraction is valid)."""
    # -gradient at q for the new load: q balanced the old one, so the load change alone
    b = ds * model.elastic.reduce_gradient(model.f_ext.reshape(-1))
    if model.has_driver:
        b[model.t_index] += model.k_drive * (model.t_target - model.t(q))
    if not b.any():
        return q
    d = model.linsolve.resolve(b)
    if d is None or not np.all(np.isfinite(d)):
        return None
    model.counters["predictor_solves"] += 1  # (resolves, but no chord steps)
    return _cut(model, q, d)


def _cut(model: Model, q, d):
    """q + alpha d with the largest collision-free alpha <= 1, halved up to four times
    while an element is inverted; None if it still is."""
    alpha = 1.0
    if model.contact is not None:
        alpha = min(1.0, model.contact.max_step(model.U(q), model.U(q + d)))
    for _ in range(4):
        q_try = q + alpha * d
        if np.isfinite(model.energy(q_try)):
            return q_try
        alpha *= 0.5
    return None
