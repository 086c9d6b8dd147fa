"""Moved to :mod:`finray.sim2real.experiment`; this name is an alias of that module for one
release (the same module object: its names, private ones too, and patches on it)."""

import sys

from ..sim2real import experiment as _module

sys.modules[__name__] = _module
