"""Bayesian force calibration: a rig's sensor against the network, sampled with emcee.

The sensor model, per frame with the network's force ``mu`` (N, the ensemble's mean)
and its spread ``s`` (N, the heads' standard deviation, :func:`spread`):

    F_sensor = g mu + b + e,   e / v ~ Student-t(nu),  v^2 = sigma^2 + (rho g mu)^2 + (kappa g s)^2

``g`` the gain, ``b`` the offset (N; a sensor that was not zeroed), ``sigma`` (N) the
noise at rest, ``rho`` the relative error under load (the network's error grows with
the force), ``kappa`` the scale of the ensemble's spread (a small ensemble's spread is
a relative, not an absolute, measure of its error), ``nu`` the degrees of freedom: the
network's errors on a new scene are heavy-tailed (most frames close, a few far off, e.g.
at contact onset), which a normal law can only meet with a scale that makes most
frames' intervals too wide. Priors (:class:`Priors`): ``log g ~ Normal(0, gain_log_sd)``,
``b ~ Normal(0, offset_sd_N)`` (each fixed, at 1 and 0 N, where its sd is 0); ``log
sigma``, ``log rho`` and ``log kappa`` uniform (scale-free) within bounds; ``nu ~ Gamma(2, rate 0.1)`` within bounds (Juárez & Steel
2010: mean 20, from near-Cauchy to near-normal). The chain runs until it is at least ``min_tau_multiple`` autocorrelation
times long for every parameter (emcee's integrated time); the diagnostics are kept
with the posterior (:func:`fit_calibration`). :func:`predictive` gives each frame's
median and interval from the posterior and the network's spread.

A printed finger's force depends on its history (:mod:`finray.viscoelastic`): it relaxes
while a push is held, reads lower on the way up than down at the same shape, and its
second cycle is softer. The image follows the shape only, so where frames come with
their times and takes (``history``) the sensor model reads the network's force through
that law, fitted on the context takes:

    F_sensor = g (c + L[mu - c]) + b + e,   L: two Prony terms (``relax_fast`` and
    ``relax_slow`` of the force relaxing with the fixed times ``relax_times_s``) and the
    Mullins-type ``softening``, over each take's frames

``c`` the network's force at rest (N, :func:`time_point_fit`), ``v`` as above with
``g mu`` read as the modelled force. The relaxation times are fixed, a decade apart, and
only their fractions fitted (the collocation form of a Prony fit): the law is then
bilinear in the fractions and the softening, computed once per fit from four basis
histories (:meth:`History.basis`), and the posterior has no ridge of fraction against
time (one free time, tried first, made the chains' autocorrelation 4-6x longer, see
studies/print_time/README.md). Priors: the fractions uniform, each at least
``relax[0]`` and their sum at most ``relax[1]``; ``softening`` uniform within bounds;
bounds of [0, 0] fix them at 0 (the static model). The heads then learn the elastic force: they are fitted on the sensor's log with
the fitted law undone (:func:`finray.viscoelastic.unrelax`), see :func:`fit_rig`.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import CalibrationError
from ..schema import schema_default

PARAMS = (
    "gain",
    "offset_N",
    "log_sigma_N",
    "log_rho",
    "log_kappa",
    "log_nu",
    "relax_fast",
    "relax_slow",
    "softening",
)
LABELS = (
    "g",
    "b (N)",
    r"log $\sigma$ (N)",
    r"log $\rho$",
    r"log $\kappa$",
    r"log $\nu$",
    r"relax$_\mathrm{fast}$",
    r"relax$_\mathrm{slow}$",
    "softening",
)
#: the static model's parameters (before the print's time dependence): a calibration of
#: these only is read with the law's three at an elastic print's values
STATIC_PARAMS = PARAMS[:6]
#: the elastic print's two fractions and softening
ELASTIC = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Priors:
    #: 0: fixed at 1 and 0 N (:func:`fixed_params`)
    gain_log_sd: float = schema_default("evaluate.sim2real.priors.gain_log_sd")
    offset_sd_N: float = schema_default("evaluate.sim2real.priors.offset_sd_N")
    #: bounds: sigma from a tenth of a force sensor's resolution (~0.01 N) up
    sigma_N: tuple[float, float] = schema_default("evaluate.sim2real.priors.sigma_N")
    rho: tuple[float, float] = schema_default("evaluate.sim2real.priors.rho")
    kappa: tuple[float, float] = schema_default("evaluate.sim2real.priors.kappa")
    #: Student-t degrees of freedom: Gamma(shape, rate) within bounds
    nu_gamma: tuple[float, float] = schema_default("evaluate.sim2real.priors.nu_gamma")
    nu: tuple[float, float] = schema_default("evaluate.sim2real.priors.nu")
    #: the print's time dependence: two Prony fractions (each >= relax[0], their sum <=
    #: relax[1]) at the fixed ``relax_times_s`` (s), and the softening; [0, 0]: fixed at 0
    relax: tuple[float, float] = schema_default("evaluate.sim2real.priors.relax")
    relax_times_s: tuple[float, float] = schema_default("evaluate.sim2real.priors.relax_times_s")
    softening: tuple[float, float] = schema_default("evaluate.sim2real.priors.softening")

    def __post_init__(self):
        (lo, hi), (fast, slow) = self.relax, self.relax_times_s
        if hi > 0 and 2 * lo > hi:
            raise CalibrationError(
                f"priors.relax {list(self.relax)}: two fractions of at least "
                f"{lo} cannot sum to at most {hi}"
            )
        if not 0 < fast < slow:
            raise CalibrationError(
                f"priors.relax_times_s {list(self.relax_times_s)}: give the fast time, then "
                "a slower one (s)"
            )

    @property
    def time_dependent(self) -> bool:
        return self.relax[1] > 0 or self.softening[1] > 0


@dataclass(frozen=True)
class Sampler:
    """emcee's settings: ``walkers``, steps per round (``chunk``), at most ``max_steps``,
    until the chain is ``min_tau_multiple`` times the largest autocorrelation time."""

    walkers: int = schema_default("evaluate.sim2real.sampler.walkers")
    chunk: int = schema_default("evaluate.sim2real.sampler.chunk")
    max_steps: int = schema_default("evaluate.sim2real.sampler.max_steps")
    min_tau_multiple: float = schema_default("evaluate.sim2real.sampler.min_tau_multiple")
    seed: int = schema_default("evaluate.sim2real.sampler.seed")


@dataclass(frozen=True)
class RigPrior:
    """What a rig leaves unknown until its frames are seen: its gain against the
    simulation (an as-built finger's stiffness and grip; ``log g_rig ~
    Normal(gain_log_mean, gain_log_sd)``, :mod:`finray.sim2real.rig_prior`) and its
    offset (N; ``b_rig ~ Normal(0, offset_sd_N)``). With no context frames the
    calibration is fitted on the simulation's own frames, which know neither: its
    intervals then covered 3-6 % of the emulated rig's frames (docs/studies/sim2real.md, "Sim-to-real")."""

    gain_log_sd: float = schema_default("evaluate.sim2real.rig_prior.gain_log_sd")
    offset_sd_N: float = schema_default("evaluate.sim2real.rig_prior.offset_sd_N")
    gain_log_mean: float = 0.0


def spread(members) -> np.ndarray:
    """The heads' spread (N) per frame from their forces (M, N): the sample standard
    deviation (ddof 1), whose square is unbiased whatever the number of heads, so that
    a kappa fitted on the cross-fitting's heads holds for the ensemble's (ddof 0 would
    make 2 heads' spread read 1/sqrt(2) of the scale, 4 heads' sqrt(3)/2)."""
    members = np.asarray(members, dtype=np.float64)
    return members.std(0, ddof=1) if len(members) > 1 else np.zeros(members.shape[1:])


@dataclass(frozen=True)
class History:
    """What the print's law runs over: each frame's camera time ``t_s`` (s) and take
    (``segments``, a label per frame; each take's frames together, in time order), and
    the network's force at rest ``base_N`` (N, c of the module's text)."""

    t_s: np.ndarray
    segments: np.ndarray
    base_N: float = 0.0
    #: the law's starting point for the sampler: relax_fast, relax_slow, softening
    start: tuple[float, float, float] = (0.05, 0.05, 0.1)

    def __post_init__(self):
        t = np.asarray(self.t_s, dtype=np.float64)
        ids = _segment_ids(self.segments)
        if len(t) != len(ids):
            raise CalibrationError(f"{len(t)} frame times for {len(ids)} frames")
        back = (np.diff(t) <= 0) & (np.diff(ids) == 0)
        if back.any() or not np.isfinite(t).all():
            raise CalibrationError(
                "a take's frame times are not increasing (or not finite): the print's "
                "law needs each take's frames in time order"
            )

    def subset(self, keep: np.ndarray) -> "History":
        keep = np.asarray(keep)
        return replace(
            self, t_s=np.asarray(self.t_s)[keep], segments=np.asarray(self.segments)[keep]
        )

    def tiled(self, n: int) -> "History":
        """The frames ``n`` times over (one history per copy): :func:`fit_rig`'s labellings."""
        ids = _segment_ids(self.segments)
        copies = (np.arange(n)[:, None] * (ids.max() + 1 if len(ids) else 1) + ids).ravel()
        return replace(self, t_s=np.tile(np.asarray(self.t_s), n), segments=copies)

    def bind(self, mu, times_s) -> "BoundLaw":
        """The law on the network's force history ``mu`` (N,), relaxing at ``times_s`` (s)."""
        return BoundLaw(self, mu, times_s)

    def law(self, mu, fractions, softening, times_s) -> np.ndarray:
        """``c + L[mu - c]`` (P, N) for P rows of fractions (P, K) and softening (P,)."""
        return self.bind(mu, times_s)(fractions, softening)


class BoundLaw:
    """The print's law on one force history, as its bilinear form: with e = mu - c, the
    softening's drive q = e (1 - e / e_max) (:func:`finray.viscoelastic.softening_factor`)
    and R_k the Prony term of time tau_k alone, the law of fractions g and softening r is

        c + e - r q + sum_k g_k (R_k e - e - r (R_k q - q))

    (:func:`finray.viscoelastic.relax` is linear in the softened force e - r q), so that
    a fit evaluates it for every walker from four basis histories computed once."""

    def __init__(self, history: History, mu, times_s):
        from ..viscoelastic import relax, softening_factor

        self.base = float(history.base_N)
        tau = np.asarray(times_s, dtype=np.float64).ravel()
        seg = history.segments
        e = np.asarray(mu, dtype=np.float64).ravel() - self.base
        q = e * (1.0 - softening_factor(e, 1.0, seg))
        one = np.eye(len(tau))  # each row one term of fraction 1 (g_inf 0): R_k itself
        taus = np.tile(tau, (len(tau), 1))
        self.e, self.q = e, q
        self.A = relax(history.t_s, e, one, taus, np.zeros(len(tau)), seg) - e
        self.B = relax(history.t_s, q, one, taus, np.zeros(len(tau)), seg) - q

    def __call__(self, fractions, softening) -> np.ndarray:
        g = np.atleast_2d(np.asarray(fractions, dtype=np.float64))
        r = np.asarray(softening, dtype=np.float64).reshape(-1, 1)
        return self.base + self.e - r * self.q + g @ self.A - r * (g @ self.B)


def _segment_ids(labels) -> np.ndarray:
    from ..viscoelastic import _segment_ids as ids

    return ids(labels)


def log_posterior(
    theta: np.ndarray, mu, s, y, priors: Priors, weight: float = 1.0, law: BoundLaw | None = None
) -> np.ndarray:
    """Log posterior (W,) of parameter rows ``theta`` (W, 9, :data:`PARAMS`): gain,
    offset (N), log sigma (N), log rho, log kappa, log nu, the two Prony fractions,
    softening; ``mu``, ``s``, ``y`` (N,) in N. ``weight``: each frame's share of the
    likelihood (1 / the times a frame appears in ``y``). ``law``: the print's law on
    ``mu`` over the frames' times and takes (:meth:`History.bind`; None: the static
    model, the law's parameters unused)."""
    from scipy.special import gammaln

    theta = np.atleast_2d(theta)
    g, b, ls, lr, lk, ln, gf, gs, sf = (theta[:, i : i + 1] for i in range(len(PARAMS)))
    ok = g[:, 0] > 0
    bounds = [(ls, priors.sigma_N), (lr, priors.rho), (lk, priors.kappa), (ln, priors.nu)]
    for v, (lo, hi) in bounds:
        ok &= (v[:, 0] >= np.log(lo)) & (v[:, 0] <= np.log(hi))
    timed = law is not None and priors.time_dependent
    if timed:
        lo, hi = priors.relax
        ok &= (gf[:, 0] >= lo) & (gs[:, 0] >= lo) & (gf[:, 0] + gs[:, 0] <= hi)
        ok &= (sf[:, 0] >= priors.softening[0]) & (sf[:, 0] <= priors.softening[1])
    out = np.full(len(theta), -np.inf)
    if not ok.any():
        return out
    g, b, ls, lr, lk, ln = g[ok], b[ok], ls[ok], lr[ok], lk[ok], ln[ok]
    nu = np.exp(ln)
    if timed:  # the force the print's law gives from the network's elastic one
        f = g * law(np.column_stack([gf[ok, 0], gs[ok, 0]]), sf[ok, 0])
        var = np.exp(2 * ls) + (np.exp(lr) * f) ** 2 + (np.exp(lk) * g * s) ** 2
        z2 = (y - f - b) ** 2 / var
    else:
        var = np.exp(2 * ls) + (np.exp(lr) * g * mu) ** 2 + (np.exp(lk) * g * s) ** 2
        z2 = (y - g * mu - b) ** 2 / var
    ll = len(y) * (
        gammaln((nu[:, 0] + 1) / 2) - gammaln(nu[:, 0] / 2) - 0.5 * np.log(np.pi * nu[:, 0])
    ) - 0.5 * np.sum(np.log(var) + (nu + 1) * np.log1p(z2 / nu), axis=1)
    shape, rate = priors.nu_gamma
    # the Gamma prior on nu, sampled as log nu (Jacobian nu); a gain or offset of prior
    # sd 0 is fixed (:func:`fixed_params`) and has no prior term; the law's parameters
    # are uniform within their bounds
    lp = shape * ln[:, 0] - rate * nu[:, 0]
    if priors.gain_log_sd > 0:
        lg = np.log(g[:, 0])
        lp = lp - 0.5 * (lg / priors.gain_log_sd) ** 2 - lg
    if priors.offset_sd_N > 0:
        lp = lp - 0.5 * (b[:, 0] / priors.offset_sd_N) ** 2
    out[ok] = weight * ll + lp
    return out


def fixed_params(priors: Priors, timed: bool = False) -> dict[int, float]:
    """The parameters held fixed, by their index in :data:`PARAMS`: the gain at 1 where
    ``gain_log_sd`` is 0, the offset at 0 N where ``offset_sd_N`` is 0 (a model already
    fitted to the sensor's frames, whose residuals are left to the noise terms); the
    print's law at an elastic print's (0, 0, 0) where the frames have no history
    (``timed`` False), the fractions and the softening each where its bounds are [0, 0]."""
    out = {
        i: v for i, v, sd in ((0, 1.0, priors.gain_log_sd), (1, 0.0, priors.offset_sd_N)) if sd == 0
    }
    if not timed or priors.relax[1] <= 0:
        out.update({6: ELASTIC[0], 7: ELASTIC[1]})
    if not timed or priors.softening[1] <= 0:
        out[8] = ELASTIC[2]
    return out


def _full(free: np.ndarray, fixed: dict[int, float]) -> np.ndarray:
    """Parameter rows (W, 9) from rows of the free parameters, the fixed ones inserted."""
    free = np.atleast_2d(free)
    out = np.empty((len(free), len(PARAMS)))
    out[:, [i for i in range(len(PARAMS)) if i not in fixed]] = free
    for i, v in fixed.items():
        out[:, i] = v
    return out


def _start(mu, s, y, priors: Priors, weight: float = 1.0, law: BoundLaw | None = None, start=None):
    """The posterior's mode (Nelder-Mead from a least-squares line), to start the walkers:
    a full parameter row, the fixed ones at their values; ``start``: the law's (relax_fast,
    relax_slow, softening) to begin from."""
    from scipy.optimize import minimize

    timed = law is not None and priors.time_dependent
    fixed = fixed_params(priors, timed)
    x_law = _law_start(start or History.start, priors) if timed else ELASTIC
    f = law(x_law[:2], x_law[2])[0] if timed else mu
    if 0 in fixed or 1 in fixed:
        g, b = fixed.get(0, 1.0), fixed.get(1, 0.0)
        if 0 not in fixed:
            g = max(float(np.sum((y - b) * f) / max(np.sum(f * f), 1e-12)), 1e-3)
        elif 1 not in fixed:
            b = float(np.mean(y - g * f))
    else:
        A = np.column_stack([f, np.ones_like(f)])
        (g, b), *_ = np.linalg.lstsq(A, y, rcond=None)
        g = g if g > 0 else 1.0
    r = y - g * f - b
    x0 = np.array(
        [
            g,
            b,
            np.log(max(np.std(r), 2 * priors.sigma_N[0])),
            np.log(0.05),
            0.0,
            np.log(np.clip(20.0, *priors.nu)),
            *x_law,
        ]
    )
    free = [i for i in range(len(PARAMS)) if i not in fixed]
    best = minimize(
        lambda t: -log_posterior(_full(t, fixed), mu, s, y, priors, weight, law)[0],
        x0[free],
        method="Nelder-Mead",
        options={"maxiter": 4000, "xatol": 1e-6, "fatol": 1e-6},
    )
    x = _full(best.x if np.isfinite(best.fun) else x0[free], fixed)[0]
    # inside the bounds, so that every walker of the ball around it starts finite
    for i, (lo, hi) in zip((2, 3, 4, 5), (priors.sigma_N, priors.rho, priors.kappa, priors.nu)):
        x[i] = np.clip(x[i], np.log(lo) + 0.05, np.log(hi) - 0.05)
    if timed:
        x[6:9] = _law_start(x[6:9], priors)
    return x


def _law_start(law, priors: Priors) -> np.ndarray:
    """(relax_fast, relax_slow, softening) moved inside the priors' bounds by a margin
    (each fraction >= relax[0], their sum <= relax[1]), the fixed ones at 0."""
    gf, gs, sf = (float(v) for v in law)
    lo, hi = priors.relax
    out = np.zeros(3)
    if hi > 0:
        pad = 0.02 * (hi - lo)
        g = np.maximum([gf, gs], lo + pad)
        if g.sum() > hi - pad:
            g = np.maximum(g * (hi - pad) / g.sum(), lo + pad)
        out[:2] = g
    if priors.softening[1] > 0:
        lo_s, hi_s = priors.softening
        pad = 0.02 * (hi_s - lo_s)
        out[2] = np.clip(sf, lo_s + pad, hi_s - pad)
    return out


def time_point_fit(mu, y, history: History, priors: Priors) -> dict:
    """A least-squares fit of ``y = g (c + L[mu - c]) + b`` (N): the print's law seen
    through the network's force ``mu`` on the frames of ``history`` (its ``base_N``
    replaced by c, the median of ``mu`` on the frames below 5 % of its largest);
    returns ``gain``, ``offset_N``, ``base_N``, ``relax_fast`` and ``relax_slow`` (the
    fractions at ``relax_times_s``), ``softening`` and ``rest_N`` = g c + b, the sensor's
    reading at rest."""
    from scipy.optimize import least_squares

    mu, y = np.asarray(mu, dtype=np.float64), np.asarray(y, dtype=np.float64)
    top = np.max(np.abs(mu)) if len(mu) else 0.0
    rest = np.abs(mu) <= 0.05 * top
    c = float(np.median(mu[rest])) if rest.any() else 0.0
    law = replace(history, base_N=c).bind(mu, priors.relax_times_s)
    fit_relax, fit_soft = priors.relax[1] > 0, priors.softening[1] > 0
    lo_r, hi_r = priors.relax

    def unpack(x):
        return x[0], x[1], x[2:4] if fit_relax else np.zeros(2), x[4] if fit_soft else 0.0

    def residual(x):
        g, b, fr, sf = unpack(x)
        # the sum's bound as a penalty (least_squares takes boxes only)
        over = max(0.0, float(np.sum(fr)) - hi_r) * 1e3 * max(np.abs(y).max(), 1.0)
        return np.r_[g * law(fr, sf)[0] + b - y, over]

    lo = [1e-3, -np.inf, lo_r, lo_r, priors.softening[0]]
    hi = [np.inf, np.inf, max(hi_r, 1e-9), max(hi_r, 1e-9), max(priors.softening[1], 1e-9)]
    x0 = np.clip([1.0, 0.0, 0.05, 0.05, 0.1], np.array(lo) + 1e-12, np.array(hi) - 1e-12)
    best = least_squares(residual, x0, bounds=(lo, hi), x_scale="jac")
    g, b, fr, sf = unpack(best.x)
    return {
        "gain": float(g),
        "offset_N": float(b),
        "base_N": c,
        "relax_fast": float(fr[0]),
        "relax_slow": float(fr[1]),
        "relax_times_s": [float(v) for v in priors.relax_times_s],
        "softening": float(sf),
        "rest_N": float(g * c + b),
        "rmse_N": float(np.sqrt(np.mean(best.fun[:-1] ** 2))),
    }


class LawCoordinates:
    """The sampler's coordinates for the print's law: its uniform priors on bounded
    values (the fractions on the triangle ``each >= 0, sum <= relax[1]``, the softening
    on its interval) sampled through logits, with the prior's density carried by the
    Jacobian. The walkers then meet no wall where a fraction or the softening is near 0
    (an elastic print's, the common case), which made the chains mix slowly there
    (the autocorrelation 1.8x an interior optimum's, on the synthetic takes of
    tests/sim2real/test_time_calibration.py). The posterior is the same.

    Fractions: total T = relax[1] sigmoid(z6), share u = sigmoid(z7), (g_fast, g_slow) =
    (T u, T (1 - u)); softening = lo + (hi - lo) sigmoid(z8). Log Jacobian (up to a
    constant): log T + sum log sigmoid(z) (1 - sigmoid(z)) over the free ones."""

    def __init__(self, priors: Priors, fixed: dict[int, float]):
        self.priors = priors
        self.fractions = 6 not in fixed
        self.softening = 8 not in fixed

    def to_params(self, z: np.ndarray) -> np.ndarray:
        from scipy.special import expit

        x = np.array(z, dtype=np.float64, copy=True)
        if self.fractions:
            total = self.priors.relax[1] * expit(z[:, 6])
            share = expit(z[:, 7])
            x[:, 6], x[:, 7] = total * share, total * (1 - share)
        if self.softening:
            lo, hi = self.priors.softening
            x[:, 8] = lo + (hi - lo) * expit(z[:, 8])
        return x

    def to_sampler(self, x: np.ndarray) -> np.ndarray:
        from scipy.special import logit

        z = np.array(x, dtype=np.float64, copy=True)
        if self.fractions:
            total = x[:, 6] + x[:, 7]
            z[:, 6] = logit(total / self.priors.relax[1])
            z[:, 7] = logit(x[:, 6] / total)
        if self.softening:
            lo, hi = self.priors.softening
            z[:, 8] = logit((x[:, 8] - lo) / (hi - lo))
        return z

    def log_jacobian(self, z: np.ndarray) -> np.ndarray:
        from scipy.special import log_expit

        out = np.zeros(len(z))
        sides = ([6, 7] if self.fractions else []) + ([8] if self.softening else [])
        for i in sides:  # log sigmoid(z) + log (1 - sigmoid(z))
            out += log_expit(z[:, i]) + log_expit(-z[:, i])
        if self.fractions:
            out += np.log(self.priors.relax[1]) + log_expit(z[:, 6])  # log T
        return out

    def log_prob(self, z, mu, s, y, weight, law) -> np.ndarray:
        """The log posterior at the sampler's coordinates ``z`` (W, 9)."""
        z = np.atleast_2d(z)
        lp = log_posterior(self.to_params(z), mu, s, y, self.priors, weight, law)
        return lp + self.log_jacobian(z) if law is not None else lp


def fit_calibration(
    mu,
    s,
    y,
    priors: Priors | None = None,
    sampler: Sampler | None = None,
    log=print,
    weight: float = 1.0,
    history: History | None = None,
) -> dict:
    """Sample the sensor model's posterior on frames (network mean ``mu``, spread ``s``,
    sensor ``y``; N). Returns ``{"posterior": {"names", "samples"}, "summary",
    "diagnostics", "priors", "sampler"}``; ``diagnostics["ok"]``: the chain is long
    enough and the acceptance fraction within 0.2-0.5. ``weight`` and ``history`` (the
    print's law over the frames' times; None: static): see :func:`log_posterior`."""
    import emcee

    priors, sampler = priors or Priors(), sampler or Sampler()
    mu, s, y = (np.asarray(a, dtype=np.float64).ravel() for a in (mu, s, y))
    keep = np.isfinite(mu) & np.isfinite(s) & np.isfinite(y)
    mu, s, y = mu[keep], s[keep], y[keep]
    if history is not None and not priors.time_dependent:
        history = None
    if history is not None:
        history = history.subset(keep)
    law = None if history is None else history.bind(mu, priors.relax_times_s)
    if len(y) < 10:
        raise CalibrationError(f"too few frames to calibrate ({len(y)}; at least 10)")
    rng = np.random.default_rng(sampler.seed)
    fixed = fixed_params(priors, history is not None)
    free = [i for i in range(len(PARAMS)) if i not in fixed]
    x0 = _start(mu, s, y, priors, weight, law, None if history is None else history.start)
    warp = LawCoordinates(priors, fixed)
    x0 = warp.to_sampler(x0[None])[0][free]
    p0 = x0 + 1e-3 * rng.standard_normal((sampler.walkers, len(free))) * np.maximum(np.abs(x0), 0.1)
    # differential-evolution moves shorten the autocorrelation; mixed with the stretch
    # move (acceptance ~0.6 here) for an acceptance fraction within 0.2-0.5
    moves = [
        (emcee.moves.DEMove(), 0.6),
        (emcee.moves.DESnookerMove(), 0.1),
        (emcee.moves.StretchMove(), 0.3),
    ]
    ens = emcee.EnsembleSampler(
        sampler.walkers,
        len(free),
        lambda t: warp.log_prob(_full(t, fixed), mu, s, y, weight, law),
        vectorize=True,
        moves=moves,
    )
    ens.random_state = np.random.RandomState(sampler.seed).get_state()  # replayable moves
    state, tau, n = p0, None, 0
    while n < sampler.max_steps:
        state = ens.run_mcmc(state, sampler.chunk, progress=False)
        n += sampler.chunk
        tau = emcee.autocorr.integrated_time(ens.get_chain(), tol=0)
        log(
            f"  calibration: {n} steps, autocorrelation time {np.max(tau):.1f} steps "
            f"({n / np.max(tau):.0f} tau)"
        )
        if n >= sampler.min_tau_multiple * np.max(tau):
            break
    acc = ens.acceptance_fraction
    burn = int(np.ceil(5 * np.max(tau)))
    thin = max(1, int(np.max(tau) / 2))
    flat = warp.to_params(_full(ens.get_chain(discard=burn, thin=thin, flat=True), fixed))
    if len(flat) > 4000:
        flat = flat[rng.choice(len(flat), 4000, replace=False)]
    diag = {
        "tau_steps": dict(zip([PARAMS[i] for i in free], map(float, tau))),
        "steps": int(n),
        "walkers": sampler.walkers,
        "steps_over_tau_min": float(n / np.max(tau)),
        "acceptance_fraction": {
            "mean": float(acc.mean()),
            "min": float(acc.min()),
            "max": float(acc.max()),
        },
        "burn_in_steps": burn,
        "thin": thin,
        "n_samples": int(len(flat)),
    }
    diag["ok"] = bool(
        diag["steps_over_tau_min"] >= sampler.min_tau_multiple and 0.2 <= acc.mean() <= 0.5
    )
    return {
        "posterior": {"names": list(PARAMS), "samples": flat.tolist()},
        "summary": summarise(flat),
        "diagnostics": diag,
        "n_frames": int(len(y)),
        "likelihood_weight": weight,
        "fixed": {PARAMS[i]: v for i, v in fixed.items()},
        # the print's law: the network's force at rest that it acts from (N); None: static
        "history_base_N": None if history is None else float(history.base_N),
        "priors": asdict(priors),
        "sampler": asdict(sampler),
    }


def summarise(samples: np.ndarray) -> dict:
    """Median and 2.5/5/95/97.5 % quantiles per parameter; sigma (N), rho, kappa and nu
    also unlogged."""
    samples = np.asarray(samples)
    cols = dict(zip(PARAMS, samples.T))
    for k in ("log_sigma_N", "log_rho", "log_kappa", "log_nu"):
        if k in cols:
            cols[k[4:]] = np.exp(cols[k])
    if "relax_fast" in cols:  # the fraction relaxed after long: both terms
        cols["relax"] = cols["relax_fast"] + cols["relax_slow"]
    return {
        k: {
            "median": float(np.median(v)),
            **{f"q{q:g}": float(np.percentile(v, q)) for q in (2.5, 5, 95, 97.5)},
        }
        for k, v in cols.items()
    }


def posterior_samples(calibration: dict) -> np.ndarray:
    """The posterior's samples (S, 9) of :data:`PARAMS`; a calibration of the static
    model's six (:data:`STATIC_PARAMS`, before the print's law) with the law elastic."""
    theta = np.asarray(calibration["posterior"]["samples"], dtype=np.float64)
    names = tuple(calibration["posterior"].get("names") or PARAMS[: theta.shape[1]])
    if names not in (PARAMS, STATIC_PARAMS):
        raise CalibrationError(
            f"the calibration's parameters {list(names)} are not this version's "
            f"{list(PARAMS)}: run finray calibrate again"
        )
    if theta.shape[1] == len(STATIC_PARAMS):
        theta = np.column_stack([theta, np.tile(ELASTIC, (len(theta), 1))])
    return theta


def is_time_dependent(calibration: dict) -> bool:
    """Whether the calibration reads the network's force through the print's law."""
    return calibration.get("history_base_N") is not None


def law_times(calibration: dict) -> tuple[float, ...]:
    """The relaxation times (s) of a calibration's two Prony fractions."""
    times = calibration.get("priors", {}).get("relax_times_s", Priors.relax_times_s)
    return tuple(float(v) for v in times)


def predictive(
    calibration: dict,
    mu,
    s,
    level: float = schema_default("evaluate.sim2real.level"),
    seed: int = 0,
    chunk: int = 1000,
    rig: RigPrior | None = None,
    history: History | None = None,
) -> dict:
    """Each frame's sensor force under the posterior (N): ``median``, ``lo``, ``hi``
    (the central ``level`` interval), from one draw per posterior sample; ``rig``: a
    new rig's unknown gain and offset drawn on top of each sample (:class:`RigPrior`);
    ``history``: the frames' times and takes, through which a time-dependent
    calibration reads ``mu`` (its ``base_N`` is the calibration's; None: read static)."""
    theta = posterior_samples(calibration)
    g, b = theta[:, :1], theta[:, 1:2]
    if rig is not None and (rig.gain_log_sd > 0 or rig.offset_sd_N > 0 or rig.gain_log_mean != 0):
        draw = np.random.default_rng([seed, 1]).standard_normal((len(theta), 2))
        g = g * np.exp(rig.gain_log_mean + rig.gain_log_sd * draw[:, :1])
        b = b + rig.offset_sd_N * draw[:, 1:2]
    sig, rho, kap, nu = (np.exp(theta[:, i : i + 1]) for i in (2, 3, 4, 5))
    mu, s = np.asarray(mu, dtype=np.float64).ravel(), np.asarray(s, dtype=np.float64).ravel()
    f = None
    if history is not None and is_time_dependent(calibration):
        h = replace(history, base_N=float(calibration["history_base_N"]))
        f = h.law(mu, theta[:, 6:8], theta[:, 8], law_times(calibration))  # (S, N)
    rng = np.random.default_rng(seed)
    q = (50.0, 50 * (1 - level), 50 * (1 + level))
    out = np.empty((3, len(mu)))
    for i in range(0, len(mu), chunk):
        m = mu[None, i : i + chunk] if f is None else f[:, i : i + chunk]
        sp = s[None, i : i + chunk]
        sd = np.sqrt(sig**2 + (rho * g * m) ** 2 + (kap * g * sp) ** 2)
        draws = g * m + b + sd * rng.standard_t(np.broadcast_to(nu, sd.shape))
        out[:, i : i + chunk] = np.percentile(draws, q, axis=0)
    return {"median": out[0], "lo": out[1], "hi": out[2], "level": level}


class CalibratedStream:
    """A calibration applied frame by frame, causally (``finray predict --calibration``
    on files, videos and live sources): :meth:`step` takes a frame's time (s; None where
    the source has none), the network's force and spread (N) and returns the frame's
    median and interval, the print's law run over the frames so far. A time not after
    the last starts a new history (a new video)."""

    def __init__(self, calibration: dict, level: float | None = None):
        from ..viscoelastic import Response

        self.calibration = calibration
        self.level = float(calibration.get("level", 0.9) if level is None else level)
        theta = posterior_samples(calibration)
        self.g, self.b = theta[:, 0], theta[:, 1]
        self.sig, self.rho, self.kap, self.nu = (np.exp(theta[:, i]) for i in (2, 3, 4, 5))
        self.timed = is_time_dependent(calibration)
        self.base = float(calibration.get("history_base_N") or 0.0)
        times = np.tile(law_times(calibration), (len(theta), 1))
        self.law = Response(theta[:, 6:8], times, theta[:, 8]) if self.timed else None
        self.frames = 0

    def step(self, t_s: float | None, mu: float, s: float) -> dict:
        """One frame's ``median``, ``lo``, ``hi`` (N) and ``level``."""
        rng = np.random.default_rng(self.frames)
        self.frames += 1
        m = self.base + self.law.step(t_s, float(mu) - self.base) if self.timed else float(mu)
        sd = np.sqrt(self.sig**2 + (self.rho * self.g * m) ** 2 + (self.kap * self.g * s) ** 2)
        draws = self.g * m + self.b + sd * rng.standard_t(self.nu)
        q = (50.0, 50 * (1 - self.level), 50 * (1 + self.level))
        med, lo, hi = np.percentile(draws, q)
        return {"median": float(med), "lo": float(lo), "hi": float(hi), "level": self.level}


def coverage(y, band: dict) -> float:
    """Fraction of frames whose ``y`` lies inside the band's interval."""
    y = np.asarray(y, dtype=np.float64)
    return float(np.mean((y >= band["lo"]) & (y <= band["hi"])))


def read_calibration(path: str | Path) -> dict:
    """A ``calibration.json`` (:func:`fit_calibration`'s output and its ``model``), or a
    one-line :class:`CalibrationError`."""
    path = Path(path)
    if not path.is_file():
        raise CalibrationError(f"no calibration at {path}")
    try:
        cal = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"{path} is not JSON ({type(exc).__name__})") from None
    samples = cal.get("posterior", {}).get("samples") if isinstance(cal, dict) else None
    if (
        not samples
        or np.asarray(samples).ndim != 2
        or np.asarray(samples).shape[1] not in (len(PARAMS), len(STATIC_PARAMS))
    ):
        raise CalibrationError(f"{path} has no posterior samples ({', '.join(PARAMS)})")
    base = cal.get("history_base_N")
    if base is not None and (
        isinstance(base, bool) or not isinstance(base, (int, float)) or not np.isfinite(base)
    ):
        raise CalibrationError(
            f"{path}: history_base_N must be a finite number or null, got {base!r}"
        )
    law = posterior_samples(cal)[:, 6:]
    if np.any(law < 0) or np.any(law[:, :2].sum(1) >= 1) or np.any(law[:, 2] >= 1):
        raise CalibrationError(
            f"{path}: relaxed fractions (their sum) and softening samples must lie in [0, 1)"
        )
    try:
        times = np.asarray(law_times(cal) if isinstance(cal.get("priors"), dict) else (1.0, 1.0))
    except (TypeError, ValueError):
        times = np.zeros(0)
    if times.shape != (2,) or not np.isfinite(times).all() or np.any(times <= 0):
        raise CalibrationError(f"{path}: priors.relax_times_s must be two times > 0 s")
    if not np.isfinite(np.asarray(samples, dtype=np.float64)).all():
        raise CalibrationError(f"{path}: posterior samples that are not finite numbers")
    level = cal.get("level", 0.9)
    if isinstance(level, bool) or not isinstance(level, (int, float)) or not 0 < level < 1:
        raise CalibrationError(
            f"{path}: level must be a number in (0, 1) (the predictive interval's), got {level!r}"
        )
    if "model" in cal and not _in_folder(cal["model"]):
        raise CalibrationError(
            f"{path}: model {cal['model']!r} is not a file in the calibration's own folder"
        )
    return cal


def _in_folder(name) -> bool:
    """Whether ``name`` (a calibration's ``model``) names a path inside the folder it is
    relative to: not absolute, no ``..``, not the folder itself."""
    from pathlib import PurePath

    if not isinstance(name, str) or not name:
        return False
    p = PurePath(name)
    return not p.is_absolute() and bool(p.parts) and ".." not in p.parts


def take_folder_names(takes) -> list[str]:
    """The names of the take folders (``<out>.ingest/<name>/`` of :func:`calibrate_takes`),
    or a one-line :class:`CalibrationError`: a take whose path ends in ``.`` or ``..``
    (no name of its own), or two takes of one name (the second would overwrite the
    first's ingest)."""
    names: dict[str, Path] = {}
    for take in map(Path, takes):
        name = take.name
        if name in ("", ".", ".."):
            raise CalibrationError(
                f"take {take}: its path has no folder name of its own (give the folder, "
                f"e.g. {take.resolve().name or take.resolve()})"
            )
        if name in names:
            raise CalibrationError(
                f"takes {names[name]} and {take} have the same folder name '{name}' "
                "(each take is ingested into a folder of its name): rename one"
            )
        names[name] = take
    return list(names)


def corner_figure(calibration: dict, title: str = ""):
    """Corner plot of the posterior (corner.py), 5/50/95 % quantiles marked; the
    matplotlib figure (the caller saves and closes it)."""
    import matplotlib

    matplotlib.use("Agg")
    import corner

    samples = posterior_samples(calibration)
    fixed = calibration.get("fixed", {})
    keep = [i for i, p in enumerate(PARAMS) if p not in fixed and np.ptp(samples[:, i]) > 0]
    fig = corner.corner(
        samples[:, keep],
        labels=[LABELS[i] for i in keep],
        quantiles=[0.05, 0.5, 0.95],
        show_titles=True,
        title_fmt=".3f",
        title_kwargs={"fontsize": 8},
        label_kwargs={"fontsize": 9},
    )
    d = calibration["diagnostics"]
    fig.suptitle(
        f"{title}\n{d['steps']} steps x {d['walkers']} walkers, "
        f"{d['steps_over_tau_min']:.0f} tau, acceptance {d['acceptance_fraction']['mean']:.2f}",
        fontsize=9,
        y=1.02,
    )
    return fig


def shard_times(shards) -> np.ndarray:
    """The camera time (s) of every frame of ingested shards, in order."""
    t = []
    for path in shards:
        with np.load(path, allow_pickle=False) as f:
            t.append(f["t_s"])
    return np.concatenate(t)


#: the cross-fitting choices of :func:`fold_units`
FOLDS = ("object", "take", "half", "both")


def fold_units(table, folds: str) -> list[np.ndarray]:
    """The cross-fitting labellings of context frames (a table with ``take``, ``t_s``
    and, for ``object``, ``object``): ``take`` (each take predicted by heads fitted
    without it: a new scene), ``half`` (each take's second half by heads fitted on the
    first halves, and back: a new moment of a seen scene), ``both``, or ``object`` (each
    object predicted by heads fitted without any of its takes: a new object, as the test
    objects are; with a single object, as ``take``: a new height is nearer a new object
    than a seen take's other half is). A single take has halves only."""
    if folds not in FOLDS:
        raise ValueError(f"the folds must be one of {', '.join(FOLDS)}, not {folds!r}")
    if folds == "object":
        if "object" not in table:
            raise ValueError("object folds need the frames' objects (an 'object' column)")
        if table["object"].nunique() >= 2:
            return [table["object"].to_numpy()]
        folds = "take"
    late = table.groupby("take")["t_s"].transform(lambda s: s > s.median()).to_numpy()
    sets = []
    if folds in ("take", "both") and table["take"].nunique() >= 2:
        sets.append(table["take"].to_numpy())
    if folds in ("half", "both") or not sets:
        sets.append(np.where(late, "2nd half", "1st half"))
    return sets


def cross_fitted(model, features, force_N, units, fit, anchor=None):
    """Each frame's ensemble mean and spread (N) from heads fitted without its unit
    (``units``: a label per frame, e.g. its take): what the network does on frames it
    has not seen, the residuals a calibration needs.

    Each fold fits as many heads as the ensemble has (``fit.members``): a spread from
    fewer heads is a noisier measure (that of 2 heads falls below a tenth of the
    heads' true spread on 8 % of frames, that of 4 on 0.14 %: chi-square with M - 1
    degrees of freedom), and a calibration fitted on it reads that noise as heavy
    tails, which widens the intervals of the ensemble it is then applied to. ``anchor``
    (:class:`finray.sim2real.adapt.SimAnchor`): fitted beside each fold's frames, its gain and
    offset from them alone."""
    from dataclasses import replace

    from .adapt import fit_heads, head_forces

    units = np.asarray(units)
    mu, sd = np.full(len(units), np.nan), np.full(len(units), np.nan)
    labels = sorted(set(units.tolist()))
    if len(labels) < 2:
        raise CalibrationError(f"cross-fitting needs at least two units of frames, got {labels}")
    y = np.asarray(force_N, dtype=np.float32)
    for j, u in enumerate(labels):
        out = units == u
        heads = fit_heads(
            model,
            features[~out],
            y[~out],
            replace(fit, seed=fit.seed + 101 * (j + 1)),
            anchor=anchor,
        )
        P = head_forces(model, heads, features[out])
        mu[out], sd[out] = P.mean(0), spread(P)
    return mu, sd


def fit_rig(
    model,
    features,
    force_N,
    unit_sets,
    fit,
    priors: Priors | None = None,
    sampler: Sampler | None = None,
    log=print,
    anchor=None,
    history: History | None = None,
):
    """A rig's head ensemble (:func:`finray.sim2real.adapt.fit_heads` on every frame, beside
    ``anchor``'s simulated frames where given) and its sensor calibration, sampled on the
    cross-fitted predictions (:func:`cross_fitted`) of every labelling in ``unit_sets``
    (each a label per frame; the frames enter once per labelling). Returns (heads,
    calibration dict).

    With the frames' ``history`` (their times and takes) and a time-dependent prior,
    the print's law is fitted too: heads fitted on the sensor's log give a first reading
    of the elastic force, a least-squares fit of the law on it (:func:`time_point_fit`)
    says how the log relaxes and softens, and the heads are fitted again on the log with
    that law undone (:func:`finray.viscoelastic.unrelax`): an image is the shape, and the
    shape's force is what the heads should learn. The sampler then fits the law anew on
    the cross-fitted predictions of those heads."""
    from .adapt import fit_heads, head_forces
    from ..viscoelastic import PrintLaw, unrelax

    priors = priors or Priors()
    y = np.asarray(force_N, dtype=np.float64)
    target, point = y, None
    if history is not None and priors.time_dependent:
        first = fit_heads(model, features, y, fit, anchor=anchor)
        point = time_point_fit(head_forces(model, first, features).mean(0), y, history, priors)
        fractions = (point["relax_fast"], point["relax_slow"])
        law = PrintLaw(fractions, tuple(priors.relax_times_s), point["softening"])
        rest = point["rest_N"]  # the sensor's reading at rest: the law acts from there
        target = rest + unrelax(history.t_s, y - rest, law, history.segments)
        history = replace(history, base_N=rest, start=(*fractions, point["softening"]))
        log(
            "  print's law (least squares): relax "
            + " + ".join(f"{g:.3f} at {t:g} s" for g, t in zip(fractions, priors.relax_times_s))
            + f", softening {point['softening']:.3f}"
        )
    else:
        history = None
    heads = fit_heads(model, features, target, fit, anchor=anchor)
    parts = [cross_fitted(model, features, target, u, fit, anchor) for u in unit_sets]
    mu, sd = (np.concatenate(a) for a in zip(*parts))
    # each frame once per labelling: a likelihood weighted 1/len, so that the posterior
    # is not narrowed as if there were more frames
    cal = fit_calibration(
        mu,
        sd,
        np.tile(y, len(parts)),
        priors,
        sampler,
        log=log,
        weight=1.0 / len(parts),
        history=None if history is None else history.tiled(len(parts)),
    )
    cal["cross_fit"] = {
        "unit_sets": [sorted(set(np.asarray(u).tolist())) for u in unit_sets],
        "fold_members": fit.members,
        "nrmse_pct": [
            float(100 * np.sqrt(np.mean((m - y) ** 2)) / np.max(np.abs(y))) for m, _ in parts
        ],
    }
    cal["heads"] = dict(vars(fit))
    cal["sim_replay_frames"] = anchor.frames if anchor is not None else 0
    cal["law_point_fit"] = point
    return heads, cal


def calibrate_takes(
    takes,
    model_path,
    out_json,
    ingest_params,
    fit,
    folds: str = schema_default("evaluate.sim2real.folds"),
    priors: Priors | None = None,
    sampler: Sampler | None = None,
    level: float = schema_default("evaluate.sim2real.level"),
    log=print,
    no_context=None,
    replay_frames: int = 0,
) -> dict:
    """``finray calibrate``: ingest the take folders (:func:`finray.recording.ingest`,
    into ``<out>.ingest/<take>/``), fit the rig's head ensemble on the simulation-trained
    model (``model.pt``, or the ``model.ts`` it was exported to, beside it), beside
    ``replay_frames`` simulated frames of ``no_context`` (the same model's no-context
    fit, :class:`finray.sim2real.adapt.SimAnchor`) where given, and sample
    the sensor calibration on cross-fitted predictions. Writes ``out_json``, the adapted
    model ``<out>.model.ts`` (+ ``.json``; what ``finray predict --calibration`` runs), the
    takes' colour segmentation (``segment``: new frames are segmented as the takes were)
    and the corner plot ``<out>.corner.png``; returns the calibration."""
    from .adapt import HeadEnsemble, SimAnchor, encoder_features, export_ensemble
    from ..dataset import load_frames
    from ..dataset.window import InputWindow
    from ..recording import ingest
    from ..recording.ingest import check_take
    from ..train import load_checkpoint
    from ..train.export import check_sealed, check_settings
    from ..train.settings import read_settings

    take_folder_names(takes)  # each take's ingest folder its own, inside <out>.ingest/
    out_json = Path(out_json)
    model_path = Path(model_path)
    if model_path.name in ("", ".", ".."):  # no file name (with_suffix: a ValueError)
        raise CalibrationError(f"{str(model_path)!r} is not a model file (model.pt)")
    pt = model_path if model_path.suffix == ".pt" else model_path.with_suffix(".pt")
    ts_meta = Path(str(pt.with_suffix(".ts")) + ".json")
    if not pt.is_file() or not ts_meta.is_file():
        raise CalibrationError(
            f"{model_path}: need the trained model's model.pt and "
            "model.ts.json side by side (results/train/<model>/)"
        )
    # the model proves what it is before any take is ingested
    model, _ = load_checkpoint(pt)
    meta, settings_note = read_settings(ts_meta)
    if settings_note is not None:
        log(f"note: {settings_note}")
    check_settings(meta, model, ts_meta.name)
    note = check_sealed(pt.with_suffix(".ts"), meta, ("checkpoint",))
    if note is not None:
        log(f"note: {note}")
    if no_context is not None:
        from .adapt import check_no_context

        check_no_context(model, no_context)
    # the takes are cropped and scaled as the model's own training frames were
    window, _ = InputWindow.from_json(meta.get("preprocess", {}))
    ingest_params = replace(ingest_params, window=window)
    stem = out_json.with_suffix("")
    for take in map(Path, takes):  # every take checked before any is ingested (~25 s each)
        check_take(take)
    shards, names = [], []
    for take in map(Path, takes):
        log(f"ingest {take}")
        ingest(take, Path(f"{stem}.ingest") / take.name, ingest_params, log=log)
        shards.append(Path(f"{stem}.ingest") / take.name / "shard.npz")
        names.append(take.name)
    size = (model.cfg.height, model.cfg.width)
    a, table = load_frames(shards, size)
    t = [shard_times([path]) for path in shards]
    table = table.assign(t_s=np.concatenate(t), take=np.repeat(names, [len(x) for x in t]))
    feats = encoder_features(model, a["images"][:, None].astype(np.float32) / 255.0)
    y = np.asarray(a["fx_N"], dtype=np.float64)
    anchor = (
        SimAnchor.from_file(model, no_context, replay_frames) if no_context is not None else None
    )
    heads, cal = fit_rig(
        model,
        feats,
        y,
        fold_units(table, folds),
        fit,
        priors,
        sampler,
        log=log,
        anchor=anchor,
        history=History(table["t_s"].to_numpy(), table["take"].to_numpy()),
    )
    ts_path = Path(f"{stem}.model.ts")
    export_ensemble(
        HeadEnsemble(model, heads),
        ts_path,
        meta.get("preprocess", {}),
        {"base_model": str(pt), "takes": [str(p) for p in takes]},
        meta,
    )
    with np.load(shards[0]) as f:  # the takes' finger colour, to segment new frames alike
        colour = json.loads(str(f["meta"]))["colour"]
    cal.update(
        model=ts_path.name,
        base_model=str(pt),
        takes=[str(p) for p in takes],
        level=level,
        n_frames_takes=int(len(y)),
        segment={
            "colour": colour,
            "stride": ingest_params.stride,
            "min_object_frac": ingest_params.min_object_frac,
            "max_hole_frac": ingest_params.max_hole_frac,
        },
    )
    out_json.parent.mkdir(parents=True, exist_ok=True)
    out_json.write_text(json.dumps(cal))
    import matplotlib.pyplot as plt

    fig = corner_figure(cal, f"calibration on {len(names)} take(s)")
    fig.savefig(f"{stem}.corner.png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return cal
