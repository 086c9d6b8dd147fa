"""The FEA stage's errors: a failed simulation and a non-positive pivot."""
from __future__ import annotations

import numpy as np


class NotPositiveDefinite(np.linalg.LinAlgError):
    """The Cholesky factorisation met a non-positive pivot."""


class SimulationError(RuntimeError):
    """The solve failed; ``step`` is the load-step index, ``load`` the load factor
    (fraction of the push) it aimed at, ``cause`` a short reason; ``partial``: the
    frames that converged before it (``displacement_mm`` (F,), ``force_N`` (F, 2): the
    force on the object), where the solver got that far, else None."""

    def __init__(self, message: str, step: int | None = None, load: float | None = None,
                 cause: str = "", partial: dict | None = None):
        super().__init__(message)
        self.step = step
        self.load = load
        self.cause = cause
        self.partial = partial
