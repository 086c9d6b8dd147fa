"""``python -m finray``: the ``finray`` command."""

from ._start import run

run()
