"""Numba's cache of the package's kernels goes to a user cache folder, never into the
source tree (an editable install, a shared clone, a read-only install)."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import finray
from finray import numba_cache

SRC = Path(finray.__file__).parent


def _run(code: str, env: dict, cwd: Path) -> str:
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"} | env
    out = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        env=env,
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_kernels_are_cached_in_the_user_cache_not_beside_the_source(tmp_path):
    """A cached kernel of a module imported after finray writes its index and code into
    <XDG_CACHE_HOME>/finray/numba, and nothing beside the module; the package's own
    kernels are located there too."""
    cache, src = tmp_path / "cache", tmp_path / "src"
    src.mkdir()
    (src / "kern.py").write_text(
        "import numba\n\n@numba.njit(cache=True)\ndef twice(x):\n    return 2 * x\n"
    )
    out = _run(
        """
        import finray, numba, sys
        from finray.render import result
        sys.path.insert(0, ".")
        import kern
        assert kern.twice(21) == 42
        print(numba.config.CACHE_DIR)
        print(next(v for v in vars(result).values()
                   if hasattr(v, "_cache") and hasattr(v._cache, "_cache_path"))._cache._cache_path)
        """,
        {"XDG_CACHE_HOME": str(cache)},
        src,
    )
    cache_dir, kernel_path = out.splitlines()
    assert Path(cache_dir) == cache / "finray" / "numba"
    assert Path(kernel_path).is_relative_to(cache / "finray" / "numba")
    written = [p.name for p in (cache / "finray" / "numba").rglob("kern.twice*")]
    assert any(n.endswith(".nbi") for n in written) and any(n.endswith(".nbc") for n in written)
    assert not list(src.rglob("*.nb[ic]"))  # nothing beside the module


def test_a_users_numba_cache_dir_is_kept(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    assert numba_cache.cache_dir() == tmp_path / "mine"


def test_an_unwritable_user_cache_falls_back_to_the_temporary_folder(tmp_path, monkeypatch):
    """A user cache that cannot hold a folder (here a file stands where it would go) gives
    the temporary folder's finray-<user>/numba."""
    blocker = tmp_path / "not_a_folder"
    blocker.write_text("")
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setattr(numba_cache, "user_cache_dir", lambda: blocker)
    monkeypatch.setattr(numba_cache.tempfile, "gettempdir", lambda: str(tmp_path / "tmp"))
    got = numba_cache.cache_dir()
    assert got.parent.parent == tmp_path / "tmp" and got.name == "numba"
    assert got.parent.name.startswith("finray-") and got.is_dir()


def test_nothing_writable_leaves_the_cache_to_numba(tmp_path, monkeypatch):
    blocker = tmp_path / "not_a_folder"
    blocker.write_text("")
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setattr(numba_cache, "user_cache_dir", lambda: blocker)
    monkeypatch.setattr(numba_cache.tempfile, "gettempdir", lambda: str(blocker))
    assert numba_cache.cache_dir() is None
