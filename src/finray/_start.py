"""The ``finray`` command's first code (the console script, ``python -m finray``): a
SIGINT or SIGTERM that comes while Python loads the command's modules ends it with one
line and 130 / 143, nothing written (later, :func:`finray.cli.main` catches them itself,
:mod:`finray.outputs`). It imports nothing heavy, so that the window it leaves is
Python's own start."""

import os
import signal
import sys


def _stopped_while_starting(signum, frame):
    word = "interrupted" if signum == signal.SIGINT else "terminated"
    command = next((a for a in sys.argv[1:2] if not a.startswith("-")), "")
    os.write(2, f"finray{' ' + command if command else ''}: {word}; nothing written\n".encode())
    os._exit(128 + signum)


def run() -> None:
    for s in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(s) is not signal.SIG_IGN:  # a signal the parent ignores stays so
            signal.signal(s, _stopped_while_starting)
    from .cli import main

    sys.exit(main())
