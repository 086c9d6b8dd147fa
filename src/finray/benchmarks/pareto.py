"""The Pareto front of a cost/error study (lower is better on both axes)."""

from __future__ import annotations

import numpy as np


def pareto_front(cost, error) -> np.ndarray:
    """Bool mask of the non-dominated points: no other point has both a cost and an
    error at most as large and one of them smaller. Exact ties are all kept; a point
    with a non-finite cost or error is never on the front and dominates nothing."""
    cost, error = np.asarray(cost, float), np.asarray(error, float)
    ok = np.isfinite(cost) & np.isfinite(error)
    c, e = cost[ok], error[ok]
    # dominated[i]: some j with c_j <= c_i, e_j <= e_i, and one strictly less
    le = (c[None, :] <= c[:, None]) & (e[None, :] <= e[:, None])
    lt = (c[None, :] < c[:, None]) | (e[None, :] < e[:, None])
    front = np.zeros(len(cost), bool)
    front[ok] = ~(le & lt).any(axis=1)
    return front
