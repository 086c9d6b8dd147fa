"""A printed finger's time dependence: quasi-linear viscoelasticity over a force history.

One home for the law that the emulated print obeys (:mod:`finray.emulator.emulate`)
and that a rig's calibration fits and applies (:mod:`finray.sim2real.calibration`):

    F(t) = g_inf f_s(t) + sum_i  int_0^t g_i exp(-(t - s) / tau_i) df_s(s),   g_inf = 1 - sum_i g_i

the hereditary integral of quasi-linear viscoelasticity (Fung) with a Prony-series
relaxation function G(t) = g_inf + sum_i g_i exp(-t / tau_i), G(0) = 1: the elastic
force (N; the FEA's, at the push's state) is the instantaneous response, and a held
push relaxes towards g_inf of it. ``f_s`` is the elastic force after a Mullins-type
softening of what was loaded before (Ogden-Roxburgh-like, on the force):

    f_s = f_e (1 - r (1 - f_e / f_max)),   f_max the largest f_e of the history so far

so that a first loading follows the elastic curve (f_e = f_max), and unloading and every
later cycle below the earlier maximum are softer, most at half that maximum (by r / 4
of it). The law is linear in f_s and causal: :class:`Response` computes it frame by
frame (live prediction), :func:`relax` over whole histories, :func:`unrelax` inverts it
(the elastic force a sensor's log implies). Between samples the elastic force is taken
as linear in time (the exact update of a Prony term for a piecewise-linear input).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np


@dataclass(frozen=True)
class PrintLaw:
    """The print's time dependence: Prony ``fractions`` g_i (of the instantaneous force,
    sum < 1) relaxing with ``times_s`` tau_i (s), and the Mullins-type ``softening`` r
    (0: none). An empty Prony series with r = 0 is an elastic print."""

    fractions: tuple[float, ...] = ()
    times_s: tuple[float, ...] = ()
    softening: float = 0.0

    def __post_init__(self):
        g, tau = np.asarray(self.fractions, float), np.asarray(self.times_s, float)
        if g.shape != tau.shape or g.ndim != 1:
            raise ValueError(
                f"a Prony series needs one relaxation time per fraction, got "
                f"{list(self.fractions)} and {list(self.times_s)}"
            )
        if np.any(~np.isfinite(g)) or np.any(g < 0) or g.sum() >= 1:
            raise ValueError(
                f"Prony fractions must be >= 0 and sum below 1, got {list(self.fractions)}"
            )
        if np.any(~np.isfinite(tau)) or np.any(tau <= 0):
            raise ValueError(f"relaxation times must be > 0 s, got {list(self.times_s)}")
        if not 0.0 <= float(self.softening) < 1.0:
            raise ValueError(f"softening must be in [0, 1), got {self.softening}")

    @property
    def elastic(self) -> bool:
        return not any(self.fractions) and self.softening == 0

    @classmethod
    def from_config(cls, spec: dict | None) -> "PrintLaw":
        """From ``{"fractions": [...], "times_s": [...], "softening": r}`` (None or
        ``{}``: elastic)."""
        spec = spec or {}
        return cls(
            tuple(float(v) for v in spec.get("fractions", ())),
            tuple(float(v) for v in spec.get("times_s", ())),
            float(spec.get("softening", 0.0)),
        )

    def as_rows(self, n: int = 1):
        """(fractions (n, K), times (n, K), softening (n,)) for :func:`relax`."""
        g = np.tile(np.asarray(self.fractions, float), (n, 1))
        tau = np.tile(np.asarray(self.times_s, float), (n, 1))
        return g, tau, np.full(n, float(self.softening))


@nb.njit(cache=True)
def _relax(t, f, seg, g, tau, r, out):  # pragma: no cover - numba
    P, N = out.shape[0], t.shape[0]
    K = g.shape[1]
    h = np.zeros(K)
    for p in range(P):
        fmax, prev, h[:] = 0.0, 0.0, 0.0
        for k in range(N):
            if k == 0 or seg[k] != seg[k - 1]:
                fmax, prev = 0.0, 0.0
                h[:] = 0.0
                dt = 0.0
            else:
                dt = t[k] - t[k - 1]
            fe = f[p, k] if f.shape[0] > 1 else f[0, k]
            pos = max(fe, 0.0)
            if pos > fmax:
                fmax = pos
            fs = fe * (1.0 - r[p] * (1.0 - pos / fmax)) if fmax > 0.0 else fe
            df = fs - prev
            ginf = 1.0
            total = 0.0
            for i in range(K):
                ginf -= g[p, i]
                if dt > 0.0:
                    a = np.exp(-dt / tau[p, i])
                    h[i] = a * h[i] + g[p, i] * df * tau[p, i] * (1.0 - a) / dt
                else:
                    h[i] += g[p, i] * df
                total += h[i]
            out[p, k] = ginf * fs + total
            prev = fs


def relax(t_s, f_elastic, fractions, times_s, softening, segments=None) -> np.ndarray:
    """The print's force (P, N) for P parameter rows: ``fractions`` and ``times_s``
    (P, K), ``softening`` (P,); ``f_elastic`` (N,) or (P, N) (N) at increasing times
    ``t_s`` (N,) within each segment of ``segments`` (N,; an id per sample, each take's
    run of samples its own history, starting unloaded; None: one history)."""
    t = np.ascontiguousarray(t_s, dtype=np.float64)
    f = np.atleast_2d(np.asarray(f_elastic, dtype=np.float64))
    g = np.atleast_2d(np.asarray(fractions, dtype=np.float64))
    tau = np.atleast_2d(np.asarray(times_s, dtype=np.float64))
    r = np.atleast_1d(np.asarray(softening, dtype=np.float64))
    P = max(len(g), len(f), len(r))
    g, tau = np.broadcast_to(g, (P, g.shape[1])), np.broadcast_to(tau, (P, tau.shape[1]))
    r = np.broadcast_to(r, (P,))
    seg = np.zeros(len(t), np.int64) if segments is None else _segment_ids(segments)
    out = np.empty((P, len(t)))
    if len(t):
        _relax(
            t,
            np.ascontiguousarray(f),
            seg,
            np.ascontiguousarray(g),
            np.ascontiguousarray(tau),
            np.ascontiguousarray(r),
            out,
        )
    return out


def softening_factor(f_elastic, softening: float, segments=None) -> np.ndarray:
    """The Mullins-type factor (N,) ``1 - r (1 - f / f_max)`` of an elastic force history
    (N,; f_max its running maximum, each segment its own): what multiplies the force
    that drives it, and any other component of the same load."""
    f = np.maximum(np.asarray(f_elastic, dtype=np.float64), 0.0)
    seg = np.zeros(len(f), np.int64) if segments is None else _segment_ids(segments)
    fmax = np.zeros(len(f))
    for s in np.unique(seg):  # a few takes: one running maximum each
        i = seg == s
        fmax[i] = np.maximum.accumulate(f[i])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(fmax > 0, 1.0 - softening * (1.0 - f / fmax), 1.0)


def _segment_ids(segments) -> np.ndarray:
    """Integer ids (N,) of any labels, a new id wherever the label changes."""
    s = np.asarray(segments)
    change = np.r_[True, s[1:] != s[:-1]] if len(s) else np.zeros(0, bool)
    return np.cumsum(change).astype(np.int64)


def unrelax(t_s, force_N, law: PrintLaw, segments=None) -> np.ndarray:
    """The elastic force (N,) whose :func:`relax` under ``law`` is ``force_N`` (N,): the
    causal inverse, sample by sample (the law is lower triangular with a diagonal of
    g_inf + sum_i g_i tau_i (1 - a_i) / dt > 0), the softening undone on the way."""
    t = np.asarray(t_s, dtype=np.float64)
    F = np.asarray(force_N, dtype=np.float64)
    g, tau = np.asarray(law.fractions, float), np.asarray(law.times_s, float)
    ginf, r = 1.0 - g.sum(), float(law.softening)
    seg = np.zeros(len(t), np.int64) if segments is None else _segment_ids(segments)
    out = np.empty(len(t))
    h, fmax, prev = np.zeros(len(g)), 0.0, 0.0
    for k in range(len(t)):
        new = k == 0 or seg[k] != seg[k - 1]
        if new:
            h[:], fmax, prev = 0.0, 0.0, 0.0
        dt = 0.0 if new else t[k] - t[k - 1]
        if dt > 0:
            a = np.exp(-dt / tau)
            c = g * tau * (1 - a) / dt
        else:
            a, c = np.ones(len(g)), g
        fs = (F[k] - np.sum(a * h) + np.sum(c) * prev) / (ginf + np.sum(c))
        h = a * h + c * (fs - prev)
        prev = fs
        out[k] = fs if r == 0 else _unsoften(fs, fmax, r)
        fmax = max(fmax, out[k])
    return out


def _unsoften(fs: float, fmax: float, r: float) -> float:
    """The f_e of a softened force ``fs`` below the history's ``fmax`` (a new maximum,
    or a pull, where the softening does not act, is ``fs`` itself)."""
    if fs <= 0 or fs >= fmax or fmax <= 0:
        return fs
    a, b = r / fmax, 1.0 - r  # a fe^2 + b fe - fs = 0, the root >= 0, in the form that
    # stays exact as r -> 0 ((-b + sqrt(.)) / 2a cancels catastrophically there)
    return 2 * fs / (b + np.sqrt(b * b + 4 * a * fs))


class Response:
    """:func:`relax` one sample at a time for P parameter rows (a posterior's samples):
    ``step(t_s, f_elastic)`` -> the force (P,) at that time, causal (a live stream's
    frames as they come). A time not after the last starts a new history."""

    def __init__(self, fractions, times_s, softening):
        self.g = np.atleast_2d(np.asarray(fractions, dtype=np.float64))
        self.tau = np.atleast_2d(np.asarray(times_s, dtype=np.float64))
        self.r = np.atleast_1d(np.asarray(softening, dtype=np.float64))
        P = max(len(self.g), len(self.r))
        self.g = np.broadcast_to(self.g, (P, self.g.shape[1]))
        self.tau = np.broadcast_to(self.tau, (P, self.tau.shape[1]))
        self.r = np.broadcast_to(self.r, (P,))
        self.ginf = 1.0 - self.g.sum(axis=1)
        self.reset()

    def reset(self) -> None:
        P, K = self.g.shape
        self.h, self.fmax, self.prev, self.t = np.zeros((P, K)), np.zeros(P), np.zeros(P), None

    def step(self, t_s: float | None, f_elastic) -> np.ndarray:
        f = np.broadcast_to(np.asarray(f_elastic, dtype=np.float64), self.r.shape)
        if t_s is None or (self.t is not None and t_s <= self.t):
            if t_s is not None:
                self.reset()
            dt = 0.0
        else:
            dt = 0.0 if self.t is None else float(t_s) - self.t
        pos = np.maximum(f, 0.0)
        self.fmax = np.maximum(self.fmax, pos)
        with np.errstate(invalid="ignore", divide="ignore"):
            fs = np.where(self.fmax > 0, f * (1.0 - self.r * (1.0 - pos / self.fmax)), f)
        df = (fs - self.prev)[:, None]
        if dt > 0:
            a = np.exp(-dt / self.tau)
            self.h = a * self.h + self.g * df * self.tau * (1.0 - a) / dt
        else:
            self.h = self.h + self.g * df
        self.prev, self.t = fs, (None if t_s is None else float(t_s))
        return self.ginf * fs + self.h.sum(axis=1)
