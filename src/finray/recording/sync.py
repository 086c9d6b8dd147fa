"""Align the force sensor's clock to the camera's.

``offset_s`` is defined by ``camera time = sensor time + offset_s``.

Method (``xcorr``): the push force, averaged over each frame's interval (a camera
frame integrates its exposure), and an image signal of the finger's deformation are
put on fine grids (a tenth of a frame) on their own clocks, scaled from their rest
levels (5th percentile, so that rest time adds nothing) by their standard deviations, and
cross-correlated (FFT) over every lag where they overlap by at least
``min_overlap`` of the shorter one; the coefficient is normalised by the shorter
length, so a lag that matches only part of the take scores less (a take with two
pushes has a second peak one cycle away, at about half the height). The peak is
refined by a parabola through its three samples (sub-frame).

Checks, else :class:`~finray.recording.take.TakeError` "clocks cannot be aligned":
the Pearson correlation over the overlap at the peak is at least ``min_r``, and the
peak's (mean-free) coefficient stands out of the best ones over the same lags of
``n_surrogates`` phase-randomised copies of the force (same spectrum, so as smooth;
p-value <= ``alpha``). A short take with one push has few independent samples: the
test is weak there, and a take like the paper's (two pushes in 10 s) passes easily.

Uncertainty: a block bootstrap over ``n_blocks`` consecutive segments of the overlap
(the peak's correlation is a sum over segments; resampling them ``n_boot`` times and
refitting the parabola gives the spread of the offset), combined with the grid's
rounding (step / sqrt 12). The peak's half width at half height is reported too.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from .take import TakeError


def frame_average(t: np.ndarray, f: np.ndarray, t_query: np.ndarray, half_s: float) -> np.ndarray:
    """Mean of the piecewise-linear signal ``f(t)`` over ``[q - half_s, q + half_s]`` per
    query (N); NaN where the window leaves ``[t[0], t[-1]]``. ``half_s`` 0: linear
    interpolation."""
    q = np.asarray(t_query, dtype=np.float64)
    if half_s <= 0:
        out = np.interp(q, t, f)
    else:
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(t))])
        # the integral of a piecewise-linear f is piecewise quadratic; between samples
        # the linear interpolation of the cumulative integral is exact to O(dt^2 f')
        out = (_integral(t, f, cum, q + half_s) - _integral(t, f, cum, q - half_s)) / (2 * half_s)
    out[(q - half_s < t[0]) | (q + half_s > t[-1])] = np.nan
    return out


def _integral(t, f, cum, x):
    """Exact integral of the linear interpolant of f from t[0] to x."""
    i = np.clip(np.searchsorted(t, x, side="right") - 1, 0, len(t) - 2)
    dx = np.clip(x - t[i], 0.0, None)
    slope = (f[i + 1] - f[i]) / (t[i + 1] - t[i])
    return cum[i] + f[i] * dx + 0.5 * slope * dx * dx


def _standardise(x: np.ndarray) -> np.ndarray:
    """``x`` from its rest level (5th percentile) in units of its standard deviation:
    the rest contributes nothing to a correlation, so the lags at which more or less of
    it overlaps (a log that starts after the video) do not pull the peak."""
    return (x - np.percentile(x, 5)) / x.std()


def _parabola(c_m: float, c_0: float, c_p: float) -> float:
    """Vertex offset (in samples, within [-0.5, 0.5]) of the parabola through three."""
    den = c_m - 2 * c_0 + c_p
    return 0.0 if den >= 0 else float(np.clip(0.5 * (c_m - c_p) / den, -0.5, 0.5))


def align_clocks(
    t_img: np.ndarray,
    s_img: np.ndarray,
    t_force: np.ndarray,
    f: np.ndarray,
    frame_dt: float,
    *,
    min_overlap: float = 0.5,
    min_r: float = 0.5,
    alpha: float = 0.05,
    n_surrogates: int = 199,
    n_blocks: int = 10,
    n_boot: int = 200,
    seed: int = 0,
) -> dict:
    """Clock offset (s) of the sensor to the camera: ``t_img`` (s, camera) and ``s_img``
    the image signal of the frames; ``t_force`` (s, sensor) and ``f`` (N) the push
    force; ``frame_dt`` (s) the frame interval. Returns ``offset_s``,
    ``uncertainty_s``, ``bootstrap_std_s``, ``peak_halfwidth_s``, ``peak_coefficient``,
    ``pearson_r``, ``p_value``, ``grid_step_s``, ``method``."""
    dt = frame_dt / 10.0
    half = frame_dt / 2.0
    gi = np.arange(t_img[0], t_img[-1] + 1e-12, dt)
    x = np.interp(gi, t_img, s_img)
    gf = np.arange(t_force[0] + half, t_force[-1] - half + 1e-12, dt)
    if len(gf) < 10 or len(gi) < 10:
        raise TakeError(
            "clocks cannot be aligned: the force log or the video is shorter than a few frames"
        )
    y = frame_average(t_force, f, gf, half)
    if not np.isfinite(y).all():  # rounding at the ends
        ok = np.isfinite(y)
        gf, y = gf[ok], y[ok]
    if x.std() < 1e-9 * max(1.0, abs(x).max()):
        raise TakeError(
            "clocks cannot be aligned: the image signal is constant "
            "(the finger does not deform in the video)"
        )
    if y.std() < 1e-9 * max(1.0, abs(y).max()):
        raise TakeError("clocks cannot be aligned: the push force is constant")
    x, y = _standardise(x), _standardise(y)
    nx, ny = len(x), len(y)
    n_min = min(nx, ny)
    lags = signal.correlation_lags(nx, ny)  # c[lag] = sum_n x[n + lag] y[n]
    overlap = signal.correlate(np.ones(nx), np.ones(ny), method="fft")
    allowed = overlap >= min_overlap * n_min - 0.5
    c = signal.correlate(x, y, method="fft") / n_min
    score = np.where(allowed, c, -np.inf)
    k = int(np.argmax(score))
    lag = int(lags[k])
    # Pearson r over the overlap at the peak
    n0, n1 = max(0, -lag), min(ny, nx - lag)
    r = float(np.corrcoef(x[n0 + lag : n1 + lag], y[n0:n1])[0, 1])
    # significance: the best (mean-free) coefficient over the allowed lags against
    # those of phase-randomised copies of the force (same spectrum, so as smooth)
    xm, ym = x - x.mean(), y - y.mean()
    scale = 1.0 / (n_min * xm.std() * ym.std())

    def best(yy):
        return (
            float(np.max(np.where(allowed, signal.correlate(xm, yy, method="fft"), -np.inf)))
            * scale
        )

    rng = np.random.default_rng(seed)
    spec = np.fft.rfft(ym)
    observed = float(signal.correlate(xm, ym, method="fft")[k]) * scale
    null = np.empty(n_surrogates)
    for i in range(n_surrogates):  # a few hundred FFT correlations of a few thousand samples
        ph = np.exp(2j * np.pi * rng.random(len(spec)))
        ph[0] = 1.0
        null[i] = best(np.fft.irfft(np.abs(spec) * ph, ny))
    p = float((1 + np.sum(null >= observed)) / (1 + n_surrogates))
    base = float(t_img[0] - gf[0])  # offset at lag 0: gi[0] <-> gf[0]
    if not (r >= min_r and p <= alpha):
        hint = (
            " (the force anti-correlates: is push_axis's sign right?)"
            if best(-ym) > max(observed, min_r)
            else ""
        )
        raise TakeError(
            f"clocks cannot be aligned: the force and the finger's deformation "
            f"do not match at any offset (best Pearson r {r:.2f}, needs >= {min_r}; "
            f"p-value {p:.3f} against shuffled forces, needs <= {alpha}){hint}"
        )
    sub = _parabola(c[k - 1], c[k], c[k + 1]) if 0 < k < len(c) - 1 else 0.0
    offset = base + (lag + sub) * dt
    # half width at half height of the peak (s)
    above = c >= 0.5 * c[k]
    lo = k
    while lo > 0 and above[lo - 1]:
        lo -= 1
    hi = k
    while hi < len(c) - 1 and above[hi + 1]:
        hi += 1
    halfwidth = 0.5 * (hi - lo + 1) * dt
    # block bootstrap of the peak position: per-lag sums over blocks of the overlap
    w = 3
    win = np.arange(lag - w, lag + w + 1)
    n0, n1 = max(0, -win.min()), min(ny, nx - win.max())
    if n1 - n0 >= n_blocks:
        idx = np.arange(n0, n1)
        prods = x[idx[None, :] + win[:, None]] * y[idx][None, :]  # (lags, samples)
        edges = np.linspace(0, len(idx), n_blocks + 1).astype(int)
        blocks = np.add.reduceat(prods, edges[:-1], axis=1)  # (lags, blocks)
        picks = rng.integers(0, n_blocks, (n_boot, n_blocks))
        counts = np.zeros((n_boot, n_blocks))
        np.add.at(counts, (np.arange(n_boot)[:, None], picks), 1.0)
        cb = counts @ blocks.T  # (boot, lags)
        j = np.clip(np.argmax(cb, axis=1), 1, 2 * w - 1)
        rows = np.arange(n_boot)
        den = cb[rows, j - 1] - 2 * cb[rows, j] + cb[rows, j + 1]
        frac = np.where(
            den < 0, 0.5 * (cb[rows, j - 1] - cb[rows, j + 1]) / np.where(den < 0, den, -1), 0.0
        )
        boot = (win[j] + np.clip(frac, -0.5, 0.5)) * dt
        boot_std = float(np.std(boot))
    else:
        boot_std = float("nan")
    unc = float(np.hypot(boot_std if np.isfinite(boot_std) else halfwidth, dt / np.sqrt(12)))
    return {
        "offset_s": float(offset),
        "uncertainty_s": unc,
        "bootstrap_std_s": boot_std,
        "peak_halfwidth_s": float(halfwidth),
        "peak_coefficient": float(c[k]),
        "pearson_r": r,
        "p_value": p,
        "n_surrogates": n_surrogates,
        "grid_step_s": dt,
        "convention": "camera time = sensor time + offset_s",
        "method": "cross-correlation of the frame-averaged push force with the image "
        "signal (shift of the finger's edges in the base-anchored window), parabolic sub-sample peak, "
        "phase-randomised surrogates for significance, block bootstrap "
        f"({n_blocks} segments, {n_boot} resamples) for the uncertainty",
    }


def force_at_frames(
    t_frames: np.ndarray, t_force: np.ndarray, f: np.ndarray, offset_s: float, frame_dt: float
) -> np.ndarray:
    """The push force (N) at each frame (camera time, s) after alignment: the sensor's
    mean over the frame interval centred on ``t - offset_s``; NaN outside its log."""
    return frame_average(t_force, f, np.asarray(t_frames) - offset_s, frame_dt / 2.0)
