# How Snakemake itself runs the jobs: its scheduler's rate limit and its benchmark
# sampling (functions only; workflow/Snakefile's onstart calls them).
#
# These two reach into Snakemake's internals (JobScheduler.job_rate_limiter, the default
# argument of snakemake.benchmark.benchmarked), because Snakemake 9.27 has no public
# interface for either; each checks the internal's shape first and does nothing (returns
# False) where it changed, so a new Snakemake release loses the fix, never the run:
# - the rate limit: --max-jobs-per-timespan (CLI or profile) cannot switch the limiter
#   off (it takes <n>/<span> only), and every scheduler pass under any limit arms a
#   threading.Timer of that span; a long span (e.g. 1000/1h in the default profile)
#   would pile up fewer wake-ups but leaves those non-daemon timers alive after the last
#   job, so Snakemake does not exit until they fire (tried on a toy workflow: it hung
#   past its jobs). Dropping the limiter is what a local run needs.
# - the sampling interval: no flag or profile key sets it (snakemake/snakemake#851, open,
#   asks for one); the interval is benchmarked()'s default argument.
def drop_default_rate_limit(wf):
    """Drop Snakemake's job-rate limit from a local run that left it at its default
    (``--max-jobs-per-timespan 100/1s``); returns whether it did.

    Why: in Snakemake 9.27 every scheduler pass under a limit arms a 1 s timer that wakes
    the scheduler again, and every finished job adds a pass: while ready jobs wait for a
    core the timers pile up, and after N jobs the scheduler runs about N passes a second,
    each re-reading the size of every ready job's inputs. On the full run that took about
    half a core while the trainings ran beside it on two cores (docs/studies/snakemake-process.md, "Snakemake's own
    process"). A local run starts a job only when one ends, so it needs no rate limit; a
    cluster run (not local) and a limit a user sets keep theirs."""
    limit = getattr(wf.scheduling_settings, "max_jobs_per_timespan", None)
    scheduler = getattr(wf, "scheduler", None)
    if (
        limit is None
        or not wf.local_exec
        or scheduler is None
        or getattr(scheduler, "job_rate_limiter", None) is None
        or (limit.max_jobs, float(limit.timespan)) != (100, 1.0)
    ):
        return False
    scheduler.job_rate_limiter = None
    return True


def sample_benchmarks_every(seconds):
    """Make Snakemake sample a benchmarked job's CPU time and memory every ``seconds`` s
    once its first ``seconds`` half-second samples are taken (0.5: every 0.5 s
    throughout); returns whether it could.

    Why: Snakemake 9.27 samples every 30 s after a job's first 15 s and keeps the last
    sample, so a longer job's CPU time read up to 30 s low (an emulated lab take: 14.7 s
    in its benchmark file, 24.4 s by /usr/bin/time; docs/studies/snakemake-process.md, "Snakemake's own process").
    A longer interval would cost shorter jobs their accuracy: at 2 s a 5 s job read 3 s.
    The interval is the default argument of ``snakemake.benchmark.benchmarked``, which
    times every benchmarked job from this process."""
    import snakemake.benchmark

    func = getattr(snakemake.benchmark.benchmarked, "__wrapped__", None)
    names = getattr(getattr(func, "__code__", None), "co_varnames", ())[:3]
    if names != ("pid", "benchmark_record", "interval") or len(func.__defaults__ or ()) != 3:
        return False
    func.__defaults__ = (*func.__defaults__[:2], seconds)
    return True
