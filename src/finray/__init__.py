"""finray: contact force and stress of a soft Fin Ray finger from camera images,
learned from finite-element simulations. Units: mm, N, MPa, degrees."""

__version__ = "0.1.0"

from .numba_cache import configure as _configure_numba_cache

_configure_numba_cache()  # compiled kernels in the user's cache, not the source tree
