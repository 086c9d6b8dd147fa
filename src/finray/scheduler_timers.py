"""Snakemake's job-rate limit without its timers' cost (docs/studies/snakemake-process.md).

Snakemake 9 re-runs its scheduler after each pass through a ``threading.Timer`` of the
limit's span (``--max-jobs-per-timespan``), and every finished job starts another such
chain: on a full run hundreds of timers wake the scheduler, which re-reads the size of
every ready job's inputs each time.
The default profile sets a span no run reaches (``1000000/1000d``), so the timers never
fire; they are not daemon threads, though, and Python waits for them at exit.
:func:`end_timers_at_exit` cancels them once the main thread is done, through the
standard library only (no Snakemake internals): a daemon thread waits for the main
thread, which Python marks done before it waits for the others."""

from __future__ import annotations

import threading


def _cancel_when_main_ends() -> None:
    threading.main_thread().join()
    for t in threading.enumerate():
        if isinstance(t, threading.Timer):
            t.cancel()


def end_timers_at_exit() -> threading.Thread:
    """Start the daemon thread that cancels every pending ``threading.Timer`` of this
    process when its main thread ends (Snakemake's, from the Snakefile); returns it."""
    w = threading.Thread(target=_cancel_when_main_ends, name="finray-end-timers", daemon=True)
    w.start()
    return w
