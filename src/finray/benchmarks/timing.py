"""Wall and CPU time of a block or of a callable (the one timer of the benchmarks).

Wall time: ``time.perf_counter``. CPU time: the process's (``cpu="process"``, counts
helper threads, e.g. Mesa's rasteriser) or the calling thread's (``cpu="thread"``:
a one-thread runtime such as ONNX Runtime with ``intra_op_num_threads=1`` computes in
it, and on a machine shared with other jobs it is less inflated than the wall time).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

_CPU = {"process": time.process_time, "thread": time.thread_time}


class Stopwatch:
    """Wall and CPU seconds since it started: at construction (``clock = Stopwatch()``,
    then ``clock.wall_s`` runs on) or on entering a ``with`` block (``with Stopwatch()
    as t: ...``: ``t.wall_s``, ``t.cpu_s`` are the block's, frozen at its exit)."""

    def __init__(self, cpu: str = "process"):
        self._cpu = _CPU[cpu]
        self._start()

    def _start(self) -> None:
        self._wall0, self._cpu0 = time.perf_counter(), self._cpu()
        self._stopped: tuple[float, float] | None = None

    def __enter__(self) -> "Stopwatch":
        self._start()
        return self

    def __exit__(self, *exc) -> None:
        self._stopped = (time.perf_counter() - self._wall0, self._cpu() - self._cpu0)

    @property
    def wall_s(self) -> float:
        return self._stopped[0] if self._stopped else time.perf_counter() - self._wall0

    @property
    def cpu_s(self) -> float:
        return self._stopped[1] if self._stopped else self._cpu() - self._cpu0


@dataclass(frozen=True)
class CallTimes:
    """Seconds per call: the median and mean over the timed calls, wall and CPU, and the
    90th percentile of the wall time."""

    wall_s: float
    cpu_s: float
    mean_wall_s: float
    mean_cpu_s: float
    n_calls: int
    p90_wall_s: float = float("nan")


def time_calls(
    fn, n_calls: int = 1, repeats: int = 1, warmup: int = 1, cpu: str = "process"
) -> CallTimes:
    """Time ``fn(k)`` for ``k = 0 .. n_calls - 1``, ``repeats`` times, each call on its
    own, after ``warmup`` untimed calls ``fn(0)`` (first-call costs: JIT, allocators).
    ``k`` lets the callable cycle through inputs (frames)."""
    for _ in range(warmup):
        fn(0)
    clock = _CPU[cpu]
    n = max(int(n_calls), 1) * max(int(repeats), 1)
    wall, cpu_s = np.empty(n), np.empty(n)
    for i in range(n):
        t, c = time.perf_counter(), clock()
        fn(i % max(int(n_calls), 1))
        wall[i], cpu_s[i] = time.perf_counter() - t, clock() - c
    return CallTimes(
        float(np.median(wall)),
        float(np.median(cpu_s)),
        float(wall.mean()),
        float(cpu_s.mean()),
        n,
        float(np.percentile(wall, 90)),
    )


def benchmark_log(benchmark_tsv: str | Path) -> Path:
    """The log of the job that wrote the Snakemake benchmark file ``benchmark_tsv``:
    the same path with its ``benchmarks`` folder read as ``logs`` and ``.log`` for
    ``.tsv`` (every benchmarked rule keeps the two parallel; a test checks the rules)."""
    p = Path(benchmark_tsv)
    parts = list(p.with_suffix(".log").parts)
    i = len(parts) - 1 - parts[::-1].index("benchmarks")
    parts[i] = "logs"
    return Path(*parts)


def job_cpu_s(benchmark_tsv: str | Path) -> tuple[float, bool]:
    """A benchmarked job's CPU time (s) and whether it is the job's own: the last line
    of its log (:func:`finray.logs.job_cpu_s`, written by ``log_to``) where there is
    one, else the benchmark file's ``cpu_time`` (its rows summed), which Snakemake
    samples every 30 s after a job's first 15 s: a long job's reads up to 30 s low."""
    import pandas as pd

    from ..logs import job_cpu_s as logged_cpu_s

    try:
        own = logged_cpu_s(benchmark_log(benchmark_tsv))
    except ValueError:  # a path without a benchmarks folder: no log to find
        own = None
    if own is not None:
        return own, True
    return float(pd.read_csv(benchmark_tsv, sep="\t")["cpu_time"].sum()), False
