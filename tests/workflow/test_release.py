"""The newest release tag, where the checkout has tags, is the package's version or an
older one (pyproject.toml's version is the version's one home; test_docs checks that
CITATION.cff and the changelog agree with it)."""

import re
import subprocess
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _key(v: str) -> tuple[int, ...]:
    return tuple(int(x) for x in v.split("."))


def test_the_newest_tag_is_not_ahead_of_the_version():
    version = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    try:
        out = subprocess.run(
            ["git", "tag", "-l", "v*"], cwd=ROOT, capture_output=True, text=True, check=True
        ).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("no git checkout here")
    tags = [t[1:] for t in out if re.fullmatch(r"v\d+\.\d+\.\d+", t)]
    if not tags:
        pytest.skip("this checkout holds no release tags")
    assert max(map(_key, tags)) <= _key(version)
