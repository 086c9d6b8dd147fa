"""Logging for workflow jobs: send a job's stdout, stderr and warnings to its log file."""

from __future__ import annotations

import contextlib
import logging
import time
from pathlib import Path


#: The start of the last line ``log_to`` writes: the job's CPU time in s (its process and
#: the children it waited for, since the process started), which the speed table reads
#: (:func:`job_cpu_s`). Snakemake's benchmark files sample a job's CPU every 30 s after
#: its first 15 s and keep the last sample, so a long job's reads up to 30 s low; its
#: sampling interval has no public setting (snakemake/snakemake#851).
JOB_CPU = "finray job CPU: "


def process_cpu_s() -> float:
    """User and system CPU time (s) of this process and of its children it waited for."""
    import resource

    own, kids = (resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def job_cpu_s(log: str | Path) -> float | None:
    """The CPU time (s) that :func:`log_to` wrote at the end of ``log``; None without one
    (no such file, or a job that did not log through ``log_to``)."""
    try:
        lines = Path(log).read_text(errors="replace").splitlines()
    except OSError:
        return None
    for line in reversed(lines):
        if line.startswith(JOB_CPU):
            try:
                return float(line[len(JOB_CPU) :].split()[0])
            except (IndexError, ValueError):
                return None
    return None


@contextlib.contextmanager
def log_to(path: str | Path):
    """Redirect stdout/stderr and the ``logging`` root to ``path`` for the block; its last
    line is the process's CPU time so far (:data:`JOB_CPU`)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # line-buffered, so that a running job's log can be followed (tail -f)
    with (
        open(path, "w", buffering=1) as f,
        contextlib.redirect_stdout(f),
        contextlib.redirect_stderr(f),
    ):
        handler = logging.StreamHandler(f)
        logging.getLogger().addHandler(handler)
        logging.getLogger().setLevel(logging.INFO)
        logging.captureWarnings(True)
        try:
            yield f
        finally:
            logging.getLogger().removeHandler(handler)
            print(f"{JOB_CPU}{process_cpu_s():.3f} s (this process and its children)", file=f)


class Progress:
    """Progress lines of a long loop through ``logger.info`` (a workflow job's log gets
    them through :func:`log_to`): ``<what>: frame k/n, <detail>, <elapsed> s``, at most
    every ``every_s`` seconds, and always for the last frame (``every_s=0``: every frame).
    """

    def __init__(self, logger: logging.Logger, what: str, n: int, every_s: float = 30.0):
        self.logger, self.what, self.n, self.every_s = logger, what, n, every_s
        self.t0 = self.t_last = time.perf_counter()

    def __call__(self, k: int, detail: str = "") -> None:
        """Frame ``k`` (1-based) is done."""
        now = time.perf_counter()
        if k < self.n and now - self.t_last < self.every_s:
            return
        self.t_last = now
        self.logger.info(
            f"{self.what}: frame {k}/{self.n}"
            + (f", {detail}" if detail else "")
            + f", {now - self.t0:.1f} s"
        )
