"""The README and the documentation site (docs/, mkdocs.yml): the README stays short
and holds the two commands CI runs; the generated references are complete; every
tutorial's commands run (the cheap ones) or are checked (dry runs and argument
parsing, on the smoke config where a run would cost too much); the citation files
agree with the package; Snakemake's --configfile trap is refused in one line.

Tutorial commands are the lines of ```bash blocks in docs/getting-started.md and
docs/tutorials/*.md, each block preceded by a marker comment:

- ``<!-- test: run -->``: every line is run as written (``.venv/bin/`` is this
  interpreter's folder, ``/tmp/finray-tutorial`` a temporary folder);
- ``<!-- test: dry-run -->``: ``snakemake`` lines run with ``-n`` (a dry run plans the
  jobs, checks the targets and the config), ``finray`` lines are parsed;
- ``<!-- test: parse ... -->``: ``finray`` lines are parsed by the CLI's parser (their
  inputs, a trained model or a recorded take, do not exist here);
- ``<!-- test: none ... -->``: not run (the README's two commands; CI runs them).
"""

from __future__ import annotations

import importlib.util
import re
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
import yaml

from helpers import ROOT

DOCS = ROOT / "docs"
BIN = Path(sys.executable).parent
README = ROOT / "README.md"
FULL_RUN = (
    "test -d .venv || python3.11 -m venv .venv; .venv/bin/pip install -q -e . && "
    ".venv/bin/snakemake --cores 2"
)
TUTORIAL_PAGES = [
    DOCS / "getting-started.md",
    *sorted((DOCS / "tutorials").glob("*.md")),
    *sorted((DOCS / "guide").glob("*.md")),
    *sorted((DOCS / "studies").glob("*.md")),
]
TMP_MARK = "/tmp/finray-tutorial"


def _hooks():
    spec = importlib.util.spec_from_file_location("finray_docs_hooks", DOCS / "hooks.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _ci_test_command() -> str:
    lines = (ROOT / ".ci" / "run").read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if "keep this line identical" in ln)
    return lines[i + 1]


# ------------------------------------------------------------------ README


def test_readme_is_short_and_holds_the_two_commands():
    text = README.read_text()
    assert len(text.splitlines()) <= 250
    blocks = re.findall(r"```bash\n(.*?)```", text, flags=re.S)
    lines = [ln for b in blocks for ln in b.splitlines()]
    assert FULL_RUN in lines
    assert _ci_test_command() in lines


def test_readme_links_exist():
    text = README.read_text()
    for target in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text):
        if "://" in target:
            continue
        assert (ROOT / target).exists(), f"README links to missing {target}"


def test_readme_answers_link_to_the_tutorials():
    text = README.read_text()
    for page in [
        "tutorials/reproduce-paper.md",
        "tutorials/one-figure.md",
        "tutorials/predict-camera.md",
        "tutorials/own-finger-object.md",
        "tutorials/own-rig.md",
        "studies/run-cost.md",
        "CITATION.cff",
        "LICENSE",
    ]:
        assert page in text, page


# ------------------------------------------------------------------ references


def _schema_leaf_keys(props: dict, defs: dict, prefix: str = "") -> list[str]:
    keys = []
    for name, node in props.items():
        if "$ref" in node:
            node = {**defs[node["$ref"].rsplit("/", 1)[1]], **node}
        if node.get("type") == "object" and node.get("properties"):
            keys += _schema_leaf_keys(node["properties"], defs, f"{prefix}{name}.")
        else:
            keys.append(prefix + name)
    return keys


def test_config_reference_has_every_schema_key():
    hooks = _hooks()
    assert hooks.CONFIG_MARKER in (DOCS / "reference" / "configuration.md").read_text()
    ref = hooks.config_reference()
    schema = yaml.safe_load(hooks.SCHEMA.read_text())
    keys = _schema_leaf_keys(schema["properties"], schema.get("$defs", {}))
    missing = [k for k in keys if f"`{k}`" not in ref]
    assert not missing, missing
    assert "`face_heights_mm`" in ref


def test_cli_reference_has_every_subcommand():
    from finray.cli import build_parser

    hooks = _hooks()
    assert hooks.CLI_MARKER in (DOCS / "reference" / "cli.md").read_text()
    ref = hooks.cli_reference()
    for name in ["geometry", "simulate", "predict", "ingest", "calibrate"]:
        assert f"## `finray {name}`" in ref
        assert f"usage: finray {name}" in ref
    assert build_parser().prog == "finray"


def test_mkdocs_build_strict(tmp_path):
    pytest.importorskip("mkdocs")
    pytest.importorskip("material")
    pytest.importorskip("mkdocstrings")
    r = subprocess.run(
        [str(BIN / "mkdocs"), "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env={**_env(), "NO_MKDOCS_2_WARNING": "1"},
    )
    assert r.returncode == 0, r.stderr[-3000:]
    assert (tmp_path / "site" / "reference" / "configuration" / "index.html").exists()


# ------------------------------------------------------------------ citation, licence


def test_citation_licence_changelog_agree_with_the_package():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0"
    for key in ["message", "title", "authors", "version", "license", "references"]:
        assert cff.get(key), key
    assert str(cff["version"]) == project["version"]
    assert cff["license"] == project["license"] == "MIT"
    paper = cff["references"][0]
    assert paper["doi"] == "10.3389/frobt.2021.631371"
    assert [a["family-names"] for a in paper["authors"]][0] == "De Barrie"
    assert "MIT License" in (ROOT / "LICENSE").read_text()
    import finray

    assert finray.__version__ == project["version"], "pip install -e . again: a stale install"
    sections = re.findall(
        r"^## \[([^\]]+)\](?: - (\S+))?$", (ROOT / "CHANGELOG.md").read_text(), re.M
    )
    assert sections[0] == ("Unreleased", ""), "CHANGELOG.md opens with [Unreleased]"
    # the newest section is this version, released on CITATION's date
    assert sections[1] == (project["version"], str(cff["date-released"]))


# ------------------------------------------------------------------ tutorials


def _blocks(page: Path) -> list[tuple[str, list[str]]]:
    """(marker, command lines) of each ```bash block of ``page``; marker '' if none."""
    text = page.read_text()
    out = []
    for m in re.finditer(
        r"(?:<!-- test: (\S+)[^>]*-->\n)?[ \t]*```bash\n(.*?)```", text, flags=re.S
    ):
        joined = m.group(2).replace("\\\n", " ")
        cmds = []
        for ln in joined.splitlines():
            ln = re.sub(r"\s+#\s.*$", "", ln).strip()
            if ln and not ln.startswith("#"):
                cmds.append(ln)
        out.append((m.group(1) or "", cmds))
    return out


def _cases(kind: str):
    for page in TUTORIAL_PAGES:
        for k, (marker, cmds) in enumerate(_blocks(page)):
            if marker == kind:
                yield pytest.param(cmds, id=f"{page.stem}-{k}")


def _env() -> dict:
    import os

    return {**os.environ, "MPLBACKEND": "Agg", "PATH": f"{BIN}:{os.environ.get('PATH', '')}"}


def _resolve(cmd: str, tmp: Path) -> str:
    return cmd.replace(".venv/bin/", f"{BIN}/").replace(TMP_MARK, str(tmp))


def test_every_tutorial_block_is_marked():
    unmarked = [(p.name, cmds) for p in TUTORIAL_PAGES for m, cmds in _blocks(p) if not m]
    assert not unmarked, unmarked
    kinds = {m for p in TUTORIAL_PAGES for m, _ in _blocks(p)}
    assert kinds <= {"run", "dry-run", "parse", "none"}, kinds


def _parse_finray(cmd: str) -> None:
    from finray.cli import build_parser

    argv = shlex.split(cmd)
    assert argv[0].endswith("finray"), cmd
    build_parser().parse_args(argv[1:])  # SystemExit on an unknown option


def _succeeds(cmd, shell: bool = False) -> None:
    """``cmd`` (a shell line, or an argv) run from the repository exits 0."""
    r = subprocess.run(
        cmd, shell=shell, cwd=ROOT, capture_output=True, text=True, env=_env(), timeout=600
    )
    assert r.returncode == 0, f"{cmd}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}"


@pytest.mark.slow
@pytest.mark.parametrize("cmds", list(_cases("run")))
def test_tutorial_commands_run(cmds, tmp_path):
    for cmd in cmds:
        _succeeds(_resolve(cmd, tmp_path), shell=True)


#: Snakemake options that take a value; --config and --configfile(s) take every word up
#: to the next option.
_VALUE_OPTIONS = {"--cores", "-c", "--jobs", "-j", "--directory", "-d", "--workflow-profile",
                  "--profile", "--rerun-triggers", "--forcerun", "--until", "--report"}  # fmt: skip
_LIST_OPTIONS = {"--config", "-C", "--configfile", "--configfiles"}


def _merged_snakemake_calls(argvs: list[list[str]]) -> list[list[str]]:
    """The ``snakemake`` calls of ``argvs`` (finray's left out) with the same options
    merged into one, their targets before the options."""
    groups: dict[tuple, list[str]] = {}
    for argv in argvs:
        if Path(argv[0]).name != "snakemake":
            continue
        options, targets, i = [argv[0]], [], 1
        while i < len(argv):
            word = argv[i]
            i += 1
            if word in _VALUE_OPTIONS and i < len(argv):
                options += [word, argv[i]]
                i += 1
            elif word in _LIST_OPTIONS:
                options.append(word)
                while i < len(argv) and not argv[i].startswith("-"):
                    options.append(argv[i])
                    i += 1
            elif word.startswith("-"):
                options.append(word)
            else:
                targets.append(word)
        # a call without targets (rule all) is planned on its own
        groups.setdefault((tuple(options), bool(targets)), []).extend(targets)
    # targets first: after --configfile they would be read as config files
    return [[options[0], *targets, *options[1:]] for (options, _), targets in groups.items()]


def _dry_run_calls() -> list[list[str]]:
    """The Snakemake calls of every block marked dry-run, merged by their options (one
    dry run plans every target the pages give with the same options)."""
    argvs = [
        [w for w in shlex.split(cmd) if w != "-n"]
        for cmds in _cases("dry-run")
        for cmd in cmds.values[0]
    ]
    return _merged_snakemake_calls(argvs)


@pytest.mark.parametrize("cmds", list(_cases("dry-run")))
def test_tutorial_dry_run_blocks_hold_snakemake_or_finray_commands(cmds):
    for cmd in cmds:
        argv = shlex.split(cmd)
        if Path(argv[0]).name == "finray":
            _parse_finray(cmd)
        else:
            assert Path(argv[0]).name == "snakemake", cmd


@pytest.mark.slow
@pytest.mark.workflow
@pytest.mark.parametrize("argv", _dry_run_calls(), ids=lambda a: " ".join(a[1:4]))
def test_tutorial_commands_dry_run(argv, tmp_path):
    argv = [_resolve(a, tmp_path) for a in argv]
    _succeeds([argv[0], "-n", *argv[1:], "--quiet", "rules"])


def test_snakemake_calls_merge_by_their_options():
    calls = [
        ["snakemake", "--cores", "2", "a.pdf"],
        ["finray", "predict"],
        ["snakemake", "--cores", "2", "b.json", "studies"],
        ["snakemake", "--cores", "2", "d", "--configfile", "c.yaml"],
        ["snakemake", "-n", "--cores", "2"],
        ["snakemake", "--cores", "2"],
    ]
    assert _merged_snakemake_calls(calls) == [
        ["snakemake", "a.pdf", "b.json", "studies", "--cores", "2"],
        ["snakemake", "d", "--cores", "2", "--configfile", "c.yaml"],
        ["snakemake", "-n", "--cores", "2"],
        ["snakemake", "--cores", "2"],
    ]


@pytest.mark.parametrize("cmds", list(_cases("parse")))
def test_tutorial_commands_parse(cmds):
    for cmd in cmds:
        _parse_finray(cmd)


# ------------------------------------------------------------------ --configfile trap


def test_configfile_trap_is_refused_in_one_line():
    """A target after --configfile (Snakemake reads it as a config file) stops with one
    line that names it, before any job or traceback; targets first, or
    --configfile=<file>, work (the tutorials' dry runs)."""
    r = subprocess.run(
        [
            str(BIN / "snakemake"),
            "-n",
            "--cores",
            "1",
            "--configfile",
            "config/smoke.yaml",
            "paper/figures/occlusion.pdf",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=_env(),
        timeout=300,
    )
    assert r.returncode == 1
    assert r.stderr.strip().splitlines() == [
        "finray: 'paper/figures/occlusion.pdf' was read as a config file: put targets "
        "before --configfile, or use --configfile=<file>"
    ]


def test_configfile_trap_detection(tmp_path, monkeypatch):
    from snakemake_logger_plugin_finray_args import message, misread_configfile

    monkeypatch.chdir(tmp_path)
    for name in ("a.yaml", "a.yml", "b.json", "b.YAML"):
        (tmp_path / name).write_text("{}\n")
    assert misread_configfile(["--configfile", "a.yaml", "fig.pdf"]) == "fig.pdf"
    assert misread_configfile(["--configfiles", "a.yml", "b.json", "x/y.csv", "-n"]) == "x/y.csv"
    assert misread_configfile(["fig.pdf", "--configfile", "a.yaml", "b.YAML"]) is None
    assert misread_configfile(["--configfile=a.yaml", "fig.pdf"]) is None
    assert misread_configfile(["--configfile", "a.yaml", "--cores", "2", "fig.pdf"]) is None
    assert misread_configfile(["--cores", "2"]) is None
    # a .json target (no such file) is the same trap, and so is a mistyped config name
    qa = "results/lab/qa.json"
    assert misread_configfile(["--configfile", "a.yaml", qa]) == qa
    assert misread_configfile(["--configfile", "smoke.yml"]) == "smoke.yml"
    assert message(qa) == (
        f"finray: '{qa}' was read as a config file, and is no file: put targets before "
        "--configfile, or use --configfile=<file>"
    )


@pytest.mark.slow
@pytest.mark.workflow
def test_configfile_guard_logger_works_when_chosen():
    """The module must be a valid Snakemake logger plugin (or every snakemake call
    would fail on it); chosen by name it logs a dry run as the default does."""
    r = subprocess.run(
        [
            str(BIN / "snakemake"),
            "--logger",
            "finray-args",
            "-n",
            "--cores",
            "1",
            "results/geometry/finger.json",
            "--configfile=config/smoke.yaml",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=_env(),
        timeout=300,
    )
    assert r.returncode == 0, r.stderr[-2000:]


def test_readme_holds_no_lab_notebook():
    """Measurements, version comparisons and trials not taken go to the issue notes and
    docs/studies/ (issue 53): no commit hashes, no 'not taken' in the README."""
    text = README.read_text()
    assert not re.findall(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b", text)
    assert "tried and not taken" not in text.lower() and "tried, not taken" not in text.lower()


@pytest.mark.slow
@pytest.mark.workflow
def test_readme_commands_parse_or_dry_run(tmp_path):
    """The README's other commands: finray lines parse, snakemake lines plan (-n)."""
    skip = {FULL_RUN, _ci_test_command()}
    cmds = [c for _, block in _blocks(README) for c in block if c not in skip]
    assert cmds
    for cmd in cmds:
        argv = shlex.split(_resolve(cmd, tmp_path))
        name = Path(argv[0]).name
        if name == "finray":
            _parse_finray(cmd)
        elif name == "snakemake":
            argv.insert(1, "-n")
            r = subprocess.run(
                argv + ["--quiet", "rules"],
                cwd=ROOT,
                capture_output=True,
                text=True,
                env=_env(),
                timeout=600,
            )
            assert r.returncode == 0, f"{cmd}\n{r.stderr[-2000:]}"


def paragraphs(text: str) -> list[str]:
    """The paragraphs of a Markdown page: its blocks between blank lines, each list item
    one, code blocks and tables left out."""
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    out = []
    for block in re.split(r"\n\s*\n", text):
        if block.strip() and not block.lstrip().startswith("|"):
            out += re.split(r"\n(?=\s*(?:[-*]|\d+\.)\s)", block)
    return out


GUIDE_PAGES = sorted(
    [*(ROOT / "docs" / "guide").glob("*.md"), *(ROOT / "docs" / "tutorials").glob("*.md")]
) + [ROOT / "docs" / "getting-started.md", ROOT / "docs" / "index.md", ROOT / "README.md"]


@pytest.mark.parametrize("page", GUIDE_PAGES, ids=lambda p: p.stem)
def test_guide_paragraphs_stay_under_200_words(page):
    """The guides say what to do, then why, in paragraphs a reader takes in at once
    (measurements live on the studies' pages)."""
    long = [p[:60] for p in paragraphs(page.read_text()) if len(p.split()) > 200]
    assert long == []


def test_paragraphs_split_items_and_skip_code():
    text = "a b\n\n- one two\n- three\n\n```\nx y z\n```\n\n| t | u |\n"
    assert [p.split() for p in paragraphs(text)] == [
        ["a", "b"],
        ["-", "one", "two"],
        ["-", "three"],
    ]


def _python_blocks(page: Path) -> str:
    """The ```python blocks of ``page``, in order, as one program (a later block may use
    an earlier one's names)."""
    return "\n".join(re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S))


PYTHON_PAGES = [
    p for p in (*GUIDE_PAGES, *sorted(DOCS.rglob("*.md"))) if "```python" in p.read_text()
]


@pytest.mark.parametrize("page", sorted(set(PYTHON_PAGES)), ids=lambda p: p.stem)
def test_every_python_snippet_runs(page, small_model, render_png):
    """Each page's Python runs as written, on a small exported model in place of the
    run's (the same files: model.ts and model.ts.json) and a rendered camera frame as
    ``frame`` (and ``first_frames``)."""
    from PIL import Image
    import numpy as np

    code = _python_blocks(page)
    assert "results/train/" in code, "a snippet names the run's model"
    code = re.sub(r'"results/train/\w+/model\.ts"', repr(str(small_model)), code)
    frame = np.asarray(Image.open(render_png).convert("RGB"))
    exec(compile(code, str(page), "exec"), {"frame": frame, "first_frames": [frame] * 3})
