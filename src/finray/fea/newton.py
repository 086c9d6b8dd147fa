"""Newton's method on a :class:`~finray.fea.problem.Model`, CCD-bounded line search.

The exact Hessian is factorised first (quadratic convergence); when it is not positive
definite, the material tangents are projected to PSD per Gauss point and the contact
Hessians per contact (ipctk's "abs" projection) and the system is factorised again.
Near the solution (after a full step below ``chord_dx``, or a friction re-lag) the
direction is first computed with the last factorisation (a chord step, for which no
Hessian is assembled), kept only when it contracts (``chord_contraction``). Each step
is cut to the collision-free fraction found by continuous collision detection, then
backtracked (Armijo) so that the energy decreases: no accepted state is
interpenetrating or has an inverted element. Convergence needs both criteria of
:class:`NewtonOptions`: the infinity norm of the Newton step below ``tol_dx`` (mm) and
the force residual of the free DOFs below ``tol_residual`` relative to the support and
load forces (:meth:`Model.residual_norm`, from the gradient already assembled for the
step); that last, tiny step is taken too. Line-search failures and gradient-descent
fallbacks are counted in ``Model.counters``, never silent.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .problem import Model
from ..schema import schema_default


@dataclass
class NewtonOptions:
    """Newton's stopping rule: converged when the step is below ``tol_dx`` (mm,
    infinity norm) *and* the free-DOF residual below ``tol_residual`` (relative to the
    support and load forces, :meth:`Model.residual_norm`; ``residual_floor`` N/mm
    is the force scale of an unloaded model)."""

    max_iterations: int = 40
    tol_dx: float = 1e-5  # mm, infinity norm of the Newton direction
    # |g_free| / |reactions + loads| (config fea.residual_tol)
    tol_residual: float = schema_default("fea.residual_tol")
    residual_floor: float = 1e-12  # N/mm
    armijo: float = 1e-4
    min_alpha: float = 1e-10
    # chord steps: after a full step below chord_dx (mm), the next direction reuses the
    # last factorisation; kept when it is at most chord_contraction times that step (the
    # Hessian has hardly changed), else a new factorisation is made (0: never). 0.1 mm
    # saved a fifth of the factorisations, but its solves, ending on slower chord steps,
    # left a steel scene's equilibrium error above equilibrium_tol (1.04e-3)
    chord_dx: float = 1e-2
    chord_contraction: float = 0.5


@dataclass
class NewtonResult:
    """``residual``: :meth:`Model.residual_norm` at the last assembled state (before
    the final step of size < tol_dx, which in Newton's quadratic regime reduces it
    further; no assembly is spent to measure it again); ``note``: why a converged
    solve is unusual (e.g. the line search stalled at round-off)."""

    q: np.ndarray
    converged: bool
    iterations: int
    cause: str = ""
    energy: float = np.nan
    history: list = field(default_factory=list)
    residual: float = np.nan
    note: str = ""


def newton(
    model: Model,
    q0: np.ndarray,
    opts: NewtonOptions | None = None,
    relag=None,
    relags: int = 0,
    relag_dx: float = 0.0,
) -> NewtonResult:
    """Minimise the model's potential from q0 (must be valid and intersection-free).

    ``relag(q)`` changes the potential (friction re-lagged at q) ``relags`` times
    during the solve: the first once a full Newton step of at most ``relag_dx`` (mm)
    has been taken (0: at convergence), the others at convergence, where the solve
    then goes on; a re-lag that the next step already satisfies ends them. One
    solve instead of a solve per re-lag saves the convergence check of each.

    Converged: Newton step below ``opts.tol_dx`` and residual below
    ``opts.tol_residual`` (both). A backtracking line search that finds no
    decrease is counted (``model.counters["line_search_failures"]``) and ends the
    solve: converged only if the residual criterion holds there (energy round-off
    near the minimum), else not converged, with the step and residual in ``cause``.
    A non-descent direction is replaced by scaled gradient descent and counted
    (``model.counters["gradient_fallbacks"]``).

    Each iteration (:class:`_Newton`): a direction (:meth:`_Newton.direction`, made a
    descent one by :meth:`_Newton.descent`), the convergence test (with the tiny last
    step, :meth:`_Newton.last_step_taken`), the collision-free fraction of the step
    (:meth:`_Newton.collision_free`) and a backtracking line search
    (:meth:`_Newton.line_search`).
    """
    return _Newton(
        model, opts or NewtonOptions(), relag, relags if relag is not None else 0, relag_dx
    ).solve(q0)


class _Newton:
    """The state of one solve: the last full step's size (a chord step follows a small
    one), the re-lags left, the steps since the last re-lag and the history rows
    ``[E, |g|, |d|, argmax, ccd alpha, alpha, residual]``."""

    def __init__(self, model: Model, opts: NewtonOptions, relag, relags: int, relag_dx: float):
        self.model, self.opts = model, opts
        self.relag, self.relags, self.relag_dx = relag, relags, relag_dx
        self.last_step = np.inf  # |dx| of the last full Newton step taken
        self.since_relag = None  # Newton steps since the last re-lag
        self.hist: list = []

    def chord_next(self) -> bool:
        return self.last_step < self.opts.chord_dx

    def assemble(self, q):
        # a chord step needs no Hessian (it is assembled if the chord is refused)
        return self.model.evaluate(q, 1 if self.chord_next() else 2)

    def relag_at(self, q):
        """Re-lag the friction at q; the potential's new energy, gradient, Hessian."""
        self.relag(q)
        self.relags -= 1
        self.since_relag = 0
        # re-lagging near the solution hardly changes the Hessian: a chord step may
        # follow, if it is below chord_contraction * chord_dx
        self.last_step = self.opts.chord_dx * (1 - 1e-12)
        return self.assemble(q)

    def solve(self, q0: np.ndarray) -> NewtonResult:
        model, opts, cnt, hist = self.model, self.opts, self.model.counters, self.hist
        q = q0.copy()
        E, g, H = model.evaluate(q, 2)
        if not np.isfinite(E):
            return NewtonResult(q, False, 0, "initial state has an inverted element", E)
        for it in range(1, opts.max_iterations + 1):
            if not (np.all(np.isfinite(g)) and (H is None or H.all_finite())):
                return NewtonResult(q, False, it, "non-finite gradient or Hessian", E, hist)
            d, H, failed = self.direction(q, g, H)
            if failed:
                return NewtonResult(q, False, it, failed, E, hist)
            d, gd, H = self.descent(q, g, d, H)
            dmax = float(np.abs(d).max()) if len(d) else 0.0
            res = model.residual_norm(g, opts.residual_floor)  # g of this state: no assembly
            hist.append(
                [
                    E,
                    float(np.abs(g).max()) if len(g) else 0.0,
                    dmax,
                    int(np.abs(d).argmax()) if len(d) else -1,
                    1.0,
                    1.0,
                    res,
                ]
            )
            if dmax < opts.tol_dx and res <= opts.tol_residual:
                q, E = self.last_step_taken(q, d, E)
                # re-lag at the solution and go on, unless the last re-lag needed no step
                if self.relags > 0 and self.since_relag != 0:
                    E, g, H = self.relag_at(q)
                    continue
                cnt["residual_max_rel"] = max(cnt["residual_max_rel"], res)
                return NewtonResult(q, True, it, "", E, hist, res)
            alpha = self.collision_free(q, d)
            if alpha <= 0:
                return NewtonResult(q, False, it, "CCD allows no step", E, hist)
            hist[-1][4] = alpha
            found = self.line_search(q, d, E, gd, dmax, alpha)
            if found is None:
                return self.stalled(q, it, E, dmax, res)
            q, alpha, ahead = found
            hist[-1][5] = alpha
            self.last_step = dmax if alpha == 1.0 else np.inf
            if self.since_relag is not None:
                self.since_relag += 1
            if (
                self.relags > 0
                and self.since_relag is None
                and alpha == 1.0
                and dmax <= self.relag_dx
            ):
                E, g, H = self.relag_at(q)
            elif ahead:  # the accepted first trial, evaluated at q
                E, g, H = ahead
            else:
                E, g, H = self.assemble(q)
        res_last = model.residual_norm(g, opts.residual_floor)
        dmax_last = hist[-1][2] if hist else np.nan
        return NewtonResult(
            q,
            False,
            opts.max_iterations,
            f"no convergence in {opts.max_iterations} iterations "
            f"(last |dx| = {dmax_last:.2e} mm, residual {res_last:.2e})",
            E,
            hist,
            res_last,
        )

    def direction(self, q, g, H):
        """The step at q: a chord step (the last factorisation) near the solution where
        it contracts, else the Hessian factorised, projected to PSD where it is not
        positive definite. ``(d, H, None)``, or ``(None, H, why)`` where none is found."""
        model, opts = self.model, self.opts
        t0 = time.perf_counter()
        d = None
        if self.chord_next():  # near the solution: try the last factorisation
            d = model.linsolve.resolve(-g)
            if d is not None and not (
                np.all(np.isfinite(d))
                and float(g @ d) < 0
                and np.abs(d).max() <= opts.chord_contraction * self.last_step
            ):
                d = None
        if d is None and H is None:  # the chord was refused: the Hessian after all
            model.counters["chord_refused"] += 1
            t1 = time.perf_counter()
            _, _, H = model.evaluate(q, 2)
            t0 += time.perf_counter() - t1  # counted as assembly and contact, not solve
            if not H.all_finite():
                return None, H, "non-finite Hessian"
        if d is None and model.psd is not True:
            try:
                d = model.linsolve.solve(H, -g)
                if not np.all(np.isfinite(d)) or float(g @ d) >= 0:
                    d = None
            except np.linalg.LinAlgError:
                d = None
        if d is None:  # indefinite: project the material tangents and retry
            model.stats["n_projected"] = model.stats.get("n_projected", 0) + 1
            if model.psd is not True:
                _, _, H = model.evaluate(q, 2, psd=True)
            try:
                d = model.linsolve.solve(H, -g)
            except np.linalg.LinAlgError as e:
                return None, H, f"linear solve failed: {e}"
        model.stats["solve_s"] += time.perf_counter() - t0
        if not np.all(np.isfinite(d)):
            return None, H, "linear solve returned NaN"
        return d, H, None

    def descent(self, q, g, d, H):
        """``(d, g . d, H)``: d, or scaled gradient descent where d does not descend
        (should not happen with PSD Hessians; counted)."""
        gd = float(g @ d)
        if gd >= 0:
            self.model.counters["gradient_fallbacks"] += 1
            if H is None:
                _, _, H = self.model.evaluate(q, 2)
            d = -g / np.maximum(H.diagonal(), 1e-12)
            gd = float(g @ d)
        return d, gd, H

    def last_step_taken(self, q, d, E):
        """The converged solve's (tiny) last Newton step, taken where it is collision-free
        and does not raise the energy: the residual becomes O(|d|^2). ``(q, E)``."""
        model = self.model
        q_try = q + d
        ok = model.contact is None or model.contact.max_step(model.U(q), model.U(q_try)) >= 1.0
        if ok:
            E_try = model.energy(q_try)
            if np.isfinite(E_try) and E_try <= E + 1e-12 * max(1.0, abs(E)):
                return q_try, E_try
        return q, E

    def collision_free(self, q, d) -> float:
        """The largest fraction (<= 1) of the step d from q that continuous collision
        detection allows."""
        model = self.model
        if model.contact is None:
            return 1.0
        t0 = time.perf_counter()
        alpha = min(1.0, model.contact.max_step(model.U(q), model.U(q + d)))
        model.stats["ccd_s"] += time.perf_counter() - t0
        return alpha

    def line_search(self, q, d, E, gd, dmax, alpha):
        """Backtracking (Armijo) from ``alpha``: ``(q_new, alpha, ahead)``, ``ahead`` the
        first trial's evaluation where it was accepted (the next iterate's energy,
        gradient and Hessian, unless a chord step follows), else False; None where no
        decrease is found above ``min_alpha``."""
        model, opts = self.model, self.opts
        t0 = time.perf_counter()
        slack = 1e-12 * max(1.0, abs(E))
        # the first trial is evaluated with the derivatives the next iteration needs
        # (a Hessian unless it will be a chord step): most steps are taken whole, and
        # then the evaluation is that of the next iterate, not an energy made twice
        ahead = None
        while True:
            q_try = q + alpha * d
            if ahead is None:
                ahead = model.evaluate(q_try, 1 if (alpha == 1.0 and dmax < opts.chord_dx) else 2)
                E_try = ahead[0]
            else:
                ahead = False
                E_try = model.energy(q_try)
            if np.isfinite(E_try) and E_try <= E + opts.armijo * alpha * gd + slack:
                break
            alpha *= 0.5
            if alpha < opts.min_alpha:
                model.stats["line_search_s"] += time.perf_counter() - t0
                return None
        model.stats["line_search_s"] += time.perf_counter() - t0
        return q_try, alpha, ahead

    def stalled(self, q, it, E, dmax, res) -> NewtonResult:
        """The result where the line search found no decrease (counted): converged if
        the residual is within tolerance (energy differences below round-off)."""
        cnt, opts = self.model.counters, self.opts
        cnt["line_search_failures"] += 1
        if dmax < 100 * opts.tol_dx and res <= opts.tol_residual:
            # balanced forces, energy differences below round-off
            cnt["residual_max_rel"] = max(cnt["residual_max_rel"], res)
            return NewtonResult(
                q,
                True,
                it - 1,
                "",
                E,
                self.hist,
                res,
                note=f"line search stalled at |dx| = {dmax:.2e} mm "
                f"with the residual {res:.2e} within tolerance",
            )
        return NewtonResult(
            q,
            False,
            it,
            f"line search failed (no decrease) at "
            f"|dx| = {dmax:.2e} mm, residual {res:.2e} (tolerance "
            f"{opts.tol_residual:.0e})",
            E,
            self.hist,
            res,
        )
