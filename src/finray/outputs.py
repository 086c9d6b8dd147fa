"""Where a ``finray`` command's outputs go: one policy for every subcommand.

- A used ``--out`` (a folder that holds files, a file) is refused in one line unless
  ``--overwrite``; an empty folder is not used.
- The outputs are written under a temporary name beside ``--out``
  (``<out>.part-<pid>``) and moved into place (:func:`os.replace`) only when complete;
  with ``--overwrite`` the earlier outputs are replaced only then, so a run that fails
  or is stopped leaves them as they were.
- A run that fails, or that SIGINT (Ctrl-C) or SIGTERM stops at any moment, removes its
  temporary folder: ``--out`` holds the complete outputs or none.

:class:`Staged` is the policy; :func:`catch_signals` makes SIGTERM stop a run as Ctrl-C
does (:class:`Terminated`, a :class:`KeyboardInterrupt`) and :func:`held` keeps a signal
from cutting the moving into place or the clean-up short (it is raised after). In the
``finray`` command's own process a signal is not raised but ends the process where it
comes (``catch_signals(stop=...)``): the open temporary folders are removed, one line,
exit code. An exception raised into whatever Python code runs at that moment can abort
the process (a callback that C++ calls through pybind11: ``std::terminate``) or be lost
(a ctypes callback's exception is printed and dropped), as CI saw (issue 55).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import threading
from pathlib import Path

from .errors import UsageError


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread while :func:`catch_signals` is on."""


class _Signals:
    """What :func:`catch_signals` saw: ``signum``, the first signal caught (None: none);
    ``pending``, one that came while :func:`held`."""

    def __init__(self, stop=None):
        self.signum: int | None = None
        self.pending: int | None = None
        self.hold = 0
        self.stop = stop  # None: raise; else called with the signal's number, ends it
        self.raising = 0  # > 0: in a raised() block

    def handler(self, signum, frame):
        if self.stop is not None and self.signum is not None and not self.raising:
            return  # stopping already (a second signal while the first is handled)
        self.signum = self.signum or signum
        if self.hold:
            self.pending = signum
            return
        self.act(signum)

    def act(self, signum: int) -> None:
        if self.stop is None or self.raising:
            raise _exception(signum)
        for staged in reversed(_OPEN):  # what a KeyboardInterrupt's unwinding would do
            staged.discard()
        self.stop(signum)


def _exception(signum: int) -> KeyboardInterrupt:
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


_SIGNALS = _Signals()
#: the outputs moved into place by this process (:meth:`Staged.commit`)
COMMITTED: list[Path] = []
#: the open :class:`Staged` outputs (their temporary folders exist)
_OPEN: list[Staged] = []


@contextlib.contextmanager
def catch_signals(stop=None):
    """SIGINT raises :class:`KeyboardInterrupt`, SIGTERM :class:`Terminated` in the main
    thread (where the process does not ignore them); yields the record (``signum``: the
    signal caught, else None). The earlier handlers come back after.

    ``stop``: where given (the command's own process), a signal is not raised: the open
    temporary folders are removed and ``stop(signum)`` is called, which must end the
    process (:func:`os._exit`); a signal in a :func:`held` block, at its end."""
    global _SIGNALS
    _SIGNALS = record = _Signals(stop)
    old = {}
    if threading.current_thread() is threading.main_thread():
        for s in (signal.SIGINT, signal.SIGTERM):
            if signal.getsignal(s) is not signal.SIG_IGN:  # nohup, a background job
                old[s] = signal.signal(s, record.handler)
    try:
        yield record
    finally:
        if stop is None:  # (the command's process keeps them to its end)
            for s, h in old.items():
                signal.signal(s, h)


@contextlib.contextmanager
def held():
    """A signal that comes in this block is raised at its end (not inside it)."""
    record = _SIGNALS
    record.hold += 1
    try:
        yield
    finally:
        record.hold -= 1
    if not record.hold and record.pending is not None:
        signum, record.pending = record.pending, None
        record.act(signum)


@contextlib.contextmanager
def raised():
    """A signal that comes in this block is raised (:class:`KeyboardInterrupt`,
    :class:`Terminated`), in the command's process too: for a loop that Ctrl-C ends
    (a live stream's frames), which catches it."""
    record = _SIGNALS
    record.raising += 1
    try:
        yield
    finally:
        record.raising -= 1


def _listing(files: list[str]) -> str:
    return f"{len(files)}: {', '.join(files[:2])}{', ...' if len(files) > 2 else ''}"


class Staged:
    """The outputs of one run at ``out``, written under :attr:`tmp` (``<out>.part-<pid>``)
    and moved into place by :meth:`commit`.

    ``kind="folder"``: ``out`` is a folder; write into :attr:`path` (the temporary
    folder). ``kind="file"``: ``out`` is a file, written at :attr:`path` (in the
    temporary folder, under its own name) with its companions beside it, whose names
    start with ``siblings`` (e.g. ``calibration.`` for ``calibration.model.ts``); each
    entry of the temporary folder goes beside ``out``.

    :meth:`open` refuses, in one line (:class:`UsageError`), a folder ``out`` that is a
    file, a file ``out`` that is a folder, and without ``overwrite`` a used one (a
    folder that holds files; a file, or one of its companions, that exists); with it,
    one whose replacing would take away one of the run's ``inputs`` (paths) or the
    current folder. Used as a
    context manager, it commits at the end of the block, also on an exception of a type
    in ``keep`` (a failure whose report is the output), and discards on any other."""

    def __init__(
        self,
        out: str | Path,
        overwrite: bool = False,
        kind: str = "folder",
        siblings: tuple[str, ...] = (),
        option: str = "--out",
        keep: tuple[type[BaseException], ...] = (),
        inputs=(),
    ):
        if kind not in ("folder", "file"):
            raise ValueError(f"kind must be 'folder' or 'file', not {kind!r}")
        out = Path(out)
        if out.name in ("", ".", ".."):  # "." has no name to put a temporary beside
            out = Path(os.path.abspath(out))
        self.out, self.overwrite, self.kind = out, bool(overwrite), kind
        self.inputs = [Path(p) for p in inputs if p is not None]
        self.siblings, self.option, self.keep = tuple(siblings), option, tuple(keep)
        self.tmp = self.out.parent / f"{self.out.name}.part-{os.getpid()}"
        self.path = self.tmp if kind == "folder" else self.tmp / self.out.name
        self._made: Path | None = None  # the first folder above out made here

    def _used(self) -> list[str]:
        """The names that make ``out`` used (empty: free)."""
        out = self.out
        if self.kind == "folder":
            if out.is_dir():
                return sorted(p.name for p in out.iterdir())
            return [out.name] if out.exists() or out.is_symlink() else []
        used = [out.name] if out.exists() else []
        if self.siblings and out.parent.is_dir():
            used += sorted(
                p.name
                for p in out.parent.iterdir()
                if p.name != out.name
                and p.name.startswith(self.siblings)
                and ".part-" not in p.name
            )
        return used

    def check(self) -> None:
        """Refuse an ``out`` of the wrong kind, a link, a name the file system cannot
        hold with the temporary's suffix, or a used one without ``overwrite`` (with it,
        one that cannot be moved aside)."""
        out, opt = self.out, self.option
        if out.is_symlink():  # replacing it would replace the link, not what it names
            raise UsageError(
                f"{opt} {out} is a symbolic link; give what it points to "
                f"({os.path.realpath(out)}) or another {opt}"
            )
        limit = _name_max(out.parent) - NAME_ROOM
        if len(os.fsencode(out.name)) > limit:
            raise UsageError(
                f"{opt} name is {len(os.fsencode(out.name))} bytes long; at most {limit} "
                f"here (the file system's {limit + NAME_ROOM}, less room for the "
                "temporary's and the companions' suffixes)"
            )
        if self.kind == "folder" and out.exists() and not out.is_dir():
            raise UsageError(f"{opt} {out} is a file, not a folder")
        if self.kind == "file" and out.is_dir():
            raise UsageError(f"{opt} {out} is a folder, not a file")
        used = self._used()
        if used and not self.overwrite:
            what = (
                f"holds another run's results ({_listing(used)})"
                if self.kind == "folder"
                else f"exists ({_listing(used)})"
            )
            raise UsageError(f"{opt} {out} {what}; give --overwrite to replace, or another {opt}")
        if used and self.kind == "folder" and not os.access(out, os.W_OK | os.X_OK):
            raise UsageError(
                f"{opt} {out} cannot be moved aside to be replaced (no write permission "
                f"on it); give another {opt}"
            )
        if used:  # replaced: never an input of the run, nor the folder it runs in
            gone = [Path(os.path.realpath(out))]
            if self.kind == "file":
                gone += [Path(os.path.realpath(out.parent / n)) for n in used]
            for p in [*self.inputs, Path.cwd()]:
                rp = Path(os.path.realpath(p))
                if any(rp == g or g in rp.parents for g in gone):
                    what = "the current folder" if p == Path.cwd() else f"the input {p}"
                    raise UsageError(f"{opt} {out} holds {what}: --overwrite would remove it")

    def open(self) -> Path:
        """Check, make the temporary folder (and the folders above ``out``); returns
        :attr:`path`, where the run writes."""
        self.check()
        missing = [p for p in [self.out.parent, *self.out.parent.parents] if not p.exists()]
        try:
            with held():
                self.out.parent.mkdir(parents=True, exist_ok=True)
                self._made = missing[-1] if missing else None
                shutil.rmtree(self.tmp, ignore_errors=True)  # an earlier process's pid
                self.tmp.mkdir()
                _OPEN.append(self)
        except OSError as exc:
            raise UsageError(
                f"{self.option} {self.out} cannot be created ({exc.strerror or exc})"
            ) from None
        return self.path

    def shown(self, text: str) -> str:
        """``text`` with the temporary folder's paths as they are once in place."""
        if self.kind == "folder":
            return text.replace(str(self.tmp), str(self.out))
        return text.replace(str(self.tmp) + os.sep, str(self.out.parent) + os.sep)

    def commit(self) -> None:
        """Move the complete outputs into place (the earlier ones, if any, replaced); a
        move the file system refuses is one line, the outputs kept where they are."""
        with held():
            try:
                if self.kind == "folder":
                    _replace(self.tmp, self.out)
                else:
                    for entry in sorted(self.tmp.iterdir()):
                        _replace(entry, self.out.parent / entry.name)
                    self.tmp.rmdir()
            except OSError as exc:
                self._close()
                raise UsageError(
                    f"{self.option} {self.out}: the complete outputs could not be moved "
                    f"into place ({exc.strerror or exc}); they are kept in {self.tmp}"
                ) from None
            COMMITTED.append(self.out)
            self._close()

    def discard(self) -> None:
        """Remove the temporary folder (and the folders made above ``out``, if empty)."""
        with held():
            shutil.rmtree(self.tmp, ignore_errors=True)
            self._close()
            if self._made is not None:
                for p in [self.out.parent, *self.out.parent.parents]:
                    try:
                        p.rmdir()
                    except OSError:
                        break
                    if p == self._made:
                        break

    def _close(self) -> None:
        if self in _OPEN:
            _OPEN.remove(self)

    def __enter__(self) -> Staged:
        self.open()
        return self

    def __exit__(self, kind, exc, tb) -> bool:
        if exc is None or isinstance(exc, self.keep):
            self.commit()
        else:
            self.discard()
        return False


#: bytes of a name kept for the suffixes added to ``out``'s (``.part-<pid>``,
#: ``.old-<pid>``, a file's companions such as ``.model.ts.json``)
NAME_ROOM = 32


def _name_max(folder: Path) -> int:
    """The longest file name (bytes) the file system of ``folder`` (or of the nearest
    folder above it that exists) holds."""
    for p in [folder, *folder.parents]:
        if p.is_dir():
            try:
                return int(os.pathconf(p, "PC_NAME_MAX"))
            except (OSError, ValueError):
                break
    return 255


def _replace(src: Path, dest: Path) -> None:
    """``src`` at ``dest``; an earlier folder there is moved aside first, removed after."""
    if dest.is_dir() and not dest.is_symlink():
        old = dest.with_name(f"{dest.name}.old-{os.getpid()}")
        shutil.rmtree(old, ignore_errors=True)
        dest.rename(old)
        src.rename(dest)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(src, dest)
