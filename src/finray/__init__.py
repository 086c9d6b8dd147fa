"""finray: contact force and stress of a soft Fin Ray finger from camera images,
learned from finite-element simulations. Units: mm, N, MPa, degrees."""

import sys as _sys

if _sys.argv[:1] == ["-m"] or _sys.argv[:1] and _sys.argv[0].rsplit("/", 1)[-1] == "finray":
    # the `finray` command is starting (python -m finray[.cli], whose argv[0] is "-m"
    # while its packages load; the console script): a signal while its modules load
    # ends it in one line (finray._start)
    from ._start import catch_while_starting

    catch_while_starting()

from .numba_cache import configure as _configure_numba_cache

_configure_numba_cache()  # compiled kernels in the user's cache, not the source tree

from importlib.metadata import PackageNotFoundError as _NotFound  # noqa: E402
from importlib.metadata import version as _version  # noqa: E402

try:  # one home: pyproject.toml's version, as pip installed it
    __version__ = _version("finray")
except _NotFound:  # the source tree on sys.path without an install
    __version__ = "0+unknown"
