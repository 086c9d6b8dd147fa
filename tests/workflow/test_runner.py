"""How Snakemake runs the jobs (workflow/rules/helpers/runner.smk), on toy workflows.

The Snakefile drops Snakemake's default job-rate limit: under it, every finished job
leaves a timer that wakes the scheduler each second while a ready job waits; a toy
workflow of short jobs counts the threads of Snakemake's own process (Linux's /proc)
while a ready job waits for cores. And it samples a benchmarked job every 0.5 s: a job
of 20 s of CPU reads as such in its benchmark file, not as its first 15 s."""

import subprocess
import sys

import pytest

from helpers import ROOT

pytestmark = [pytest.mark.slow, pytest.mark.workflow]  # not in `pytest -m "not slow"`

HELPER = ROOT / "workflow" / "rules" / "helpers" / "runner.smk"
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


def snakemake_in(tmp_path, snakefile, *args):
    """Run ``snakefile`` in ``tmp_path`` (``args`` on the command line); fail on errors."""
    (tmp_path / "Snakefile").write_text(snakefile)
    r = subprocess.run(
        [sys.executable, "-m", "snakemake", "--quiet", *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr[-2000:]


def run_toy(tmp_path, *args):
    snakemake_in(tmp_path, SNAKEFILE, "--cores", "2", *args)
    return (
        (tmp_path / "dropped.txt").read_text() == "True",
        int((tmp_path / "threads.txt").read_text()),
    )


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


BENCH_SNAKEFILE = f"""
include: {str(HELPER)!r}

onstart:
    open("sampled.txt", "w").write(str(sample_benchmarks_every(0.5)))

rule busy:
    output: "busy.txt"
    benchmark: "busy.tsv"
    shell: "{sys.executable} -c 'import time; t = time.process_time()\\nwhile time.process_time() - t < 20: pass' && touch {{output}}"
"""


def test_a_long_job_s_benchmark_holds_its_cpu_time(tmp_path):
    # Snakemake's own sampling (every 30 s after the first 15 s, the last sample kept)
    # reads this job's 20 s of CPU as about 15 s
    snakemake_in(tmp_path, BENCH_SNAKEFILE, "--cores", "1")
    assert (tmp_path / "sampled.txt").read_text() == "True"
    head, values = (
        line.split("\t") for line in (tmp_path / "busy.tsv").read_text().splitlines()[:2]
    )
    assert 19.0 <= float(values[head.index("cpu_time")]) <= 21.0
