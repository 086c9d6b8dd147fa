"""``python -m finray`` and the ``finray`` console script: the ``finray`` command."""

import sys

from ._start import catch_while_starting


def run() -> None:
    catch_while_starting()  # (already on where finray/__init__ saw the command start)
    from .cli import main

    sys.exit(main())


if __name__ == "__main__":
    run()
