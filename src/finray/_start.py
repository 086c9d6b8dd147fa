"""The ``finray`` command's first code (``finray.__main__``: the console script,
``python -m finray``): a
SIGINT or SIGTERM that comes while Python loads the command's modules ends it with one
line and 130 / 143, nothing written (later, :func:`finray.cli.main` catches them itself,
:mod:`finray.outputs`). ``finray/__init__`` installs it before anything else where the
process is the command, and it imports nothing heavy, so that the window it leaves is
Python's own start (tens of ms)."""

import os
import signal
import sys


def _stopped_while_starting(signum, frame):
    word = "interrupted" if signum == signal.SIGINT else "terminated"
    command = next((a for a in sys.argv[1:2] if not a.startswith("-")), "")
    os.write(2, f"finray{' ' + command if command else ''}: {word}; nothing written\n".encode())
    os._exit(128 + signum)


def catch_while_starting() -> None:
    """SIGINT and SIGTERM end the starting command in one line (``finray/__init__`` calls
    this first where ``finray`` is the command; :func:`finray.cli.main` then catches them
    itself). A signal the parent ignores stays ignored."""
    for s in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(s) is not signal.SIG_IGN:
            signal.signal(s, _stopped_while_starting)
