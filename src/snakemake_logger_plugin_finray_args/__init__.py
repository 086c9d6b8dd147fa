"""finray's guard against the ``--configfile`` trap of Snakemake's command line.

Snakemake's ``--configfile`` takes every word that follows it, so in
``snakemake --cores 1 --configfile config/smoke.yaml paper/figures/occlusion.pdf`` the
figure is read as a second config file and the run ends in a 20-line traceback, before
any line of the workflow runs. Snakemake imports its plugins while it builds its
argument parser, before it parses the arguments: this module is found as a logger
plugin (the name ``snakemake_logger_plugin_*`` is what Snakemake looks for), and on
import it checks the command line and refuses the trap in one line (exit code 1):

    finray: 'paper/figures/occlusion.pdf' was read as a config file: put targets
    before --configfile, or use --configfile=<file>

It does nothing else: it acts only in a ``snakemake`` process, only on words after
``--configfile``/``--configfiles`` that are not YAML or JSON files on disk. The logger it
registers (``--logger finray-args``) writes Snakemake's messages to stderr unchanged;
nothing selects it by default.
"""

from __future__ import annotations

import logging
import os
import sys

from snakemake_interface_logger_plugins.base import LogHandlerBase

CONFIG_SUFFIXES = (".yaml", ".yml", ".json")
_OPTIONS = ("--configfile", "--configfiles")


def misread_configfile(argv: list[str]) -> str | None:
    """The first word of ``argv`` (Snakemake's arguments, without the program) that
    ``--configfile`` would read as a config file although it is none: a word not ending
    in .yaml/.yml/.json (a target such as a figure), or one that does but is no file (a
    target such as ``results/lab/qa.json``, or a config file's name mistyped); None
    where every such word is a config file."""
    i = 0
    while i < len(argv):
        word = argv[i]
        i += 1
        if word not in _OPTIONS:  # "--configfile=a.yaml" takes one value: no trap
            continue
        while i < len(argv) and not argv[i].startswith("-"):
            path = argv[i]
            i += 1
            if not path.lower().endswith(CONFIG_SUFFIXES) or not os.path.isfile(path):
                return path
    return None


def message(path: str) -> str:
    """The one line that refuses ``path``."""
    none = (
        ""
        if os.path.isfile(path) or not path.lower().endswith(CONFIG_SUFFIXES)
        else ", and is no file"
    )
    return (
        f"finray: '{path}' was read as a config file{none}: put targets before "
        f"--configfile, or use --configfile=<file>"
    )


def _is_snakemake(argv0: str) -> bool:
    base = os.path.basename(argv0)
    return base.startswith("snakemake") or argv0.replace(os.sep, "/").endswith(
        "snakemake/__main__.py"
    )


def _guard() -> None:
    if not sys.argv or not _is_snakemake(sys.argv[0]):
        return
    bad = misread_configfile(sys.argv[1:])
    if bad is not None:
        print(message(bad), file=sys.stderr)
        sys.exit(1)


class LogHandler(LogHandlerBase, logging.StreamHandler):
    """A plain stderr logger (the plugin interface asks for one; not used by default)."""

    def __post_init__(self) -> None:
        logging.StreamHandler.__init__(self, sys.stderr)

    def emit(self, record: logging.LogRecord) -> None:
        logging.StreamHandler.emit(self, record)

    @property
    def writes_to_stream(self) -> bool:
        return True

    @property
    def writes_to_file(self) -> bool:
        return False

    @property
    def has_filter(self) -> bool:
        return False

    @property
    def has_formatter(self) -> bool:
        return False

    @property
    def needs_rulegraph(self) -> bool:
        return False


_guard()
