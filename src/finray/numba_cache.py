"""Where Numba keeps the package's compiled kernels: a user cache folder, never the
source tree.

The kernels (``@njit(cache=True)`` in ``render`` and ``annotate``) are compiled once and
cached. Numba's own default writes the cache beside the source (``__pycache__``), so an
editable install or a clone shared by several users would get files written into it.
:func:`configure` (run on ``import finray``, before any kernel is defined) points
``NUMBA_CACHE_DIR`` at ``<user cache>/finray/numba`` instead, or at a folder of the
system's temporary folder where that one cannot be written; a ``NUMBA_CACHE_DIR`` set
by the user is kept.
"""

from __future__ import annotations

import getpass
import os
import sys
import tempfile
from pathlib import Path


def user_cache_dir() -> Path:
    """The user's cache folder (``platformdirs`` where installed, else
    ``$XDG_CACHE_HOME`` or ``~/.cache``, ``%LOCALAPPDATA%`` on Windows)."""
    try:
        import platformdirs
    except ImportError:
        pass
    else:
        return Path(platformdirs.user_cache_dir())
    if sys.platform == "win32" and os.environ.get("LOCALAPPDATA"):
        return Path(os.environ["LOCALAPPDATA"])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")


def _writable(path: Path) -> bool:
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return os.access(path, os.W_OK | os.X_OK)


def cache_dir() -> Path | None:
    """The folder the kernels are cached in: ``NUMBA_CACHE_DIR`` if set, else the first
    writable of ``<user cache>/finray/numba`` and ``<tmp>/finray-<user>/numba``; None
    where neither can be written (Numba then falls back to its own locations)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    candidates = []
    try:
        candidates.append(user_cache_dir() / "finray" / "numba")
    except (OSError, RuntimeError, KeyError):  # no home folder
        pass
    try:
        user = getpass.getuser()
    except (OSError, KeyError):
        user = str(os.getuid()) if hasattr(os, "getuid") else "user"
    candidates.append(Path(tempfile.gettempdir()) / f"finray-{user}" / "numba")
    return next((c for c in candidates if _writable(c)), None)


def configure() -> Path | None:
    """Set Numba's cache folder to :func:`cache_dir` (the environment variable for a
    Numba not imported yet, ``numba.config.CACHE_DIR`` for one already imported); the
    folder, or None where it is left to Numba."""
    path = cache_dir()
    if path is None:
        return None
    os.environ["NUMBA_CACHE_DIR"] = str(path)
    numba = sys.modules.get("numba")
    if numba is not None:
        numba.config.CACHE_DIR = str(path)
    return path
