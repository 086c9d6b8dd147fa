# How Snakemake itself runs the jobs: its scheduler's rate limit and its benchmark
# sampling (functions only; the Snakefile's onstart calls them).
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
    if (limit is None or not wf.local_exec or scheduler is None
            or getattr(scheduler, "job_rate_limiter", None) is None
            or (limit.max_jobs, float(limit.timespan)) != (100, 1.0)):
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
