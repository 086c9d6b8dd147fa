"""The Snakefile drops Snakemake's default job-rate limit (workflow/rules/helpers/
scheduler.smk): under it, every finished job leaves a timer that wakes the scheduler each
second while a ready job waits. A toy workflow of short jobs counts the threads of
Snakemake's own process (Linux's /proc) while a ready job waits for cores."""
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HELPER = ROOT / "workflow" / "rules" / "helpers" / "scheduler.smk"
JOBS = 40

SNAKEFILE = f"""
include: {str(HELPER)!r}

import os

onstart:
    open("dropped.txt", "w").write(str(drop_default_rate_limit(workflow)))
    open("pid.txt", "w").write(str(os.getpid()))

rule all:
    input: "threads.txt", "blocked.txt"

rule one:
    output: "out/{{i}}.txt"
    shell: "touch {{output}}"

# count and blocked are ready together; count goes first (priority) and blocked, which
# needs both cores, waits beside it: a ready job that waits keeps the scheduler passing
rule count:
    input: expand("out/{{i}}.txt", i=range({JOBS}))
    output: "threads.txt"
    run:
        import time
        time.sleep(2)
        status = open(f"/proc/{{open('pid.txt').read()}}/status").read()
        open(output[0], "w").write(status.split("Threads:")[1].split()[0])

rule blocked:
    input: expand("out/{{i}}.txt", i=range({JOBS}))
    output: "blocked.txt"
    threads: 2
    priority: -100
    shell: "touch {{output}}"
"""


def run_toy(tmp_path, *args):
    (tmp_path / "Snakefile").write_text(SNAKEFILE)
    r = subprocess.run([sys.executable, "-m", "snakemake", "--cores", "2", "--quiet", *args],
                       cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return ((tmp_path / "dropped.txt").read_text() == "True",
            int((tmp_path / "threads.txt").read_text()))


def test_default_rate_limit_is_dropped_and_timers_do_not_pile_up(tmp_path):
    dropped, threads = run_toy(tmp_path)
    assert dropped
    assert threads < 10


@pytest.mark.parametrize("limit", ["99/1s", "100/2s"])
def test_a_limit_the_user_sets_is_kept(tmp_path, limit):
    # and with it the timers pile up, one per finished job or so: what the drop avoids
    dropped, threads = run_toy(tmp_path, "--max-jobs-per-timespan", limit)
    assert not dropped
    assert threads > JOBS // 2
