"""Logging for workflow jobs: send a job's stdout, stderr and warnings to its log file."""
from __future__ import annotations

import contextlib
import logging
from pathlib import Path


@contextlib.contextmanager
def log_to(path: str | Path):
    """Redirect stdout/stderr and the ``logging`` root to ``path`` for the block."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # line-buffered, so that a running job's log can be followed (tail -f)
    with open(path, "w", buffering=1) as f, contextlib.redirect_stdout(f), contextlib.redirect_stderr(f):
        handler = logging.StreamHandler(f)
        logging.getLogger().addHandler(handler)
        logging.getLogger().setLevel(logging.INFO)
        logging.captureWarnings(True)
        try:
            yield f
        finally:
            logging.getLogger().removeHandler(handler)
