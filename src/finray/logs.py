"""Logging for workflow jobs: send a job's stdout, stderr and warnings to its log file."""

from __future__ import annotations

import contextlib
import logging
import time
from pathlib import Path


@contextlib.contextmanager
def log_to(path: str | Path):
    """Redirect stdout/stderr and the ``logging`` root to ``path`` for the block."""
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
