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


def test_the_default_profile_sets_a_long_rate_limit_span():
    """A 1 s span (Snakemake's default) wakes the scheduler once a second per finished
    job while a ready job waits; the profile's span is 10 s (docs/studies/snakemake-process.md)."""
    profile = yaml.safe_load(
        (ROOT / "workflow" / "profiles" / "default" / "config.yaml").read_text()
    )
    limit = MaxJobsPerTimespan.parse_choice(profile["max-jobs-per-timespan"])
    assert limit.timespan == 10 and limit.max_jobs >= 100


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
