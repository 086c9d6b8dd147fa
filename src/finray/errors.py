"""The package's exceptions, in one place; every one is a :class:`FinrayError`. Each
says in one line (``str``) what is wrong; the checks raise them at the door, before any
work or any file is written.

Every error about what a user gave (a config, options, an object, a take, a model, a
source, a frame, a device) is a :class:`BadInput`: ``finray`` prints ``finray
<command>: <message>`` and exits with 2. They are also :class:`ValueError`, so that
code that catches those keeps working. A failure part way through work that was valid
to start (an FEA scene that does not converge: :class:`SimulationError`, also a
:class:`RuntimeError`) is not bad input: ``finray`` exits with 1.
"""

from __future__ import annotations

import numpy as np


class FinrayError(Exception):
    """Base of the package's own errors."""


class BadInput(FinrayError, ValueError):
    """Input that cannot be used; ``str`` is one line (the CLI: exit code 2)."""


class UsageError(BadInput):
    """Options of a command that do not go together."""


class ConfigError(BadInput):
    """A config that cannot run; ``str(err)`` is ``'<key>: <reason>'``."""

    def __init__(self, key: str, message: str):
        super().__init__(f"{key}: {message}")
        self.key = key


class GeometryError(BadInput):
    """A geometry that cannot be built; ``key`` names the config entry at fault."""

    def __init__(self, key: str, message: str):
        super().__init__(f"{key}: {message}")
        self.key = key


class ResultError(BadInput):
    """A ``result.npz`` that does not follow the contract."""


class MediaError(BadInput):
    """A source (file or video) that cannot be read at all."""


class DeviceError(BadInput):
    """A device this machine does not have, or an unknown one."""


class EmptyMaskError(BadInput):
    """A mask without foreground: no finger to anchor a crop on."""


class TakeError(BadInput):
    """A take that cannot be ingested."""


class CalibrationError(BadInput):
    """A calibration that cannot be fitted or read."""


class InputError(BadInput):
    """Input that cannot be predicted (model, source or frame)."""


class ModelError(InputError):
    """A model file that cannot be used: not a model, one that would run code when
    loaded, or one that does not match the settings beside it (another network's, or a
    file changed since it was exported)."""


class DeviceInputError(InputError, DeviceError):
    """A device this machine does not have (``device="cuda"`` without a GPU)."""


class FrameError(InputError):
    """One frame that cannot be predicted: unreadable, not an image, or no finger in it."""


class SimulationError(FinrayError, RuntimeError):
    """An FEA solve failed part way (the CLI: exit code 1); ``step`` is the load-step
    index, ``load`` the load factor (fraction of the push) it aimed at, ``cause`` a short
    reason; ``partial``: the frames that converged before it (``displacement_mm`` (F,),
    ``force_N`` (F, 2): the force on the object), where the solver got that far, else
    None."""

    def __init__(
        self,
        message: str,
        step: int | None = None,
        load: float | None = None,
        cause: str = "",
        partial: dict | None = None,
    ):
        super().__init__(message)
        self.step = step
        self.load = load
        self.cause = cause
        self.partial = partial


class NotPositiveDefinite(FinrayError, np.linalg.LinAlgError):
    """A Cholesky factorisation met a non-positive pivot (the FEA's linear solvers; the
    solver projects the Hessian and factorises again)."""


class StabilityFailure(FinrayError, AssertionError):
    """A case of the FEA stability suite raised an error it does not expect."""
