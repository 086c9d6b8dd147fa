"""How Snakemake runs the jobs, through its public interfaces: the default profile's
job-rate limit (workflow/profiles/default) and each job's CPU time from its own log
(finray.logs.log_to's last line, read by finray.benchmarks.timing.job_cpu_s), on toy
workflows. Snakemake samples a benchmarked job's CPU every 30 s after its first 15 s and
keeps the last sample, so a job of 20 s of CPU reads about 15 s in its benchmark file;
its own figure does not depend on the sampling."""

import subprocess
import sys

import pytest
import yaml
from snakemake.settings.types import MaxJobsPerTimespan

from finray.benchmarks.timing import job_cpu_s

from helpers import ROOT

pytestmark = [pytest.mark.slow, pytest.mark.workflow]  # not in `pytest -m "not slow"`


def test_the_default_profile_sets_a_rate_limit_no_run_reaches():
    """Every pass of Snakemake's scheduler arms a timer of the limit's span and every
    finished job adds a chain of them (docs/studies/snakemake-process.md): the profile's
    span is one no run reaches, so that they never fire."""
    profile = yaml.safe_load(
        (ROOT / "workflow" / "profiles" / "default" / "config.yaml").read_text()
    )
    limit = MaxJobsPerTimespan.parse_choice(profile["max-jobs-per-timespan"])
    assert limit.timespan >= 30 * 86400 and limit.max_jobs >= 100_000


def test_a_pending_timer_does_not_keep_the_process_alive():
    """Python waits for a process's threading.Timer threads at exit; with
    end_timers_at_exit they are cancelled once the main thread is done."""
    code = """
import sys, threading
from finray.scheduler_timers import end_timers_at_exit
if sys.argv[1] == "on":
    end_timers_at_exit()
threading.Timer(3600, lambda: print("fired")).start()
print("main done", flush=True)
"""
    r = subprocess.run(
        [sys.executable, "-c", code, "on"], capture_output=True, text=True, timeout=60
    )
    assert (r.returncode, r.stdout) == (0, "main done\n"), r.stderr
    with pytest.raises(subprocess.TimeoutExpired):  # without it, the process waits
        subprocess.run([sys.executable, "-c", code, "off"], capture_output=True, timeout=3)


TIMERS_SNAKEFILE = """
from finray.scheduler_timers import end_timers_at_exit

end_timers_at_exit()

rule all:
    input: expand("out/{i}.txt", i=range(12))

rule one:
    output: "out/{i}.txt"
    shell: "touch {output}"
"""


def test_snakemake_ends_with_its_job_rate_timers_at_the_profiles_span(tmp_path):
    """The profile's span on a toy workflow that calls end_timers_at_exit, as the
    workflow does (common.smk): every job runs, and Snakemake ends (its timers of
    1000 days cancelled) instead of waiting for them."""
    (tmp_path / "Snakefile").write_text(TIMERS_SNAKEFILE)
    profile = yaml.safe_load(
        (ROOT / "workflow" / "profiles" / "default" / "config.yaml").read_text()
    )
    r = subprocess.run(
        [
            *(sys.executable, "-m", "snakemake", "--quiet", "--cores", "2"),
            *("--max-jobs-per-timespan", profile["max-jobs-per-timespan"]),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    assert len(list((tmp_path / "out").iterdir())) == 12


BUSY = """
from finray.logs import log_to

with log_to(snakemake.log[0]):
    import time

    t = time.process_time()
    while time.process_time() - t < 20:
        pass
    open(snakemake.output[0], "w").close()
"""

SNAKEFILE = """
rule busy:
    output: "busy.txt"
    log: "results/logs/busy.log"
    benchmark: "results/benchmarks/busy.tsv"
    script: "busy.py"
"""


def test_a_long_job_s_cpu_time_is_its_own(tmp_path):
    (tmp_path / "Snakefile").write_text(SNAKEFILE)
    (tmp_path / "busy.py").write_text(BUSY)
    r = subprocess.run(
        [sys.executable, "-m", "snakemake", "--quiet", "--cores", "1"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    cpu, own = job_cpu_s(tmp_path / "results" / "benchmarks" / "busy.tsv")
    assert own and 20.0 <= cpu <= 22.0
