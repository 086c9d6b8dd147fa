# The scheduler's settings (functions only; the Snakefile's onstart calls them).
def drop_default_rate_limit(wf):
    """Drop Snakemake's job-rate limit from a local run that left it at its default
    (``--max-jobs-per-timespan 100/1s``); returns whether it did.

    Why: in Snakemake 9.27 every scheduler pass under a limit arms a 1 s timer that wakes
    the scheduler again, and every finished job adds a pass: while ready jobs wait for a
    core the timers pile up, and after N jobs the scheduler runs about N passes a second,
    each re-reading the size of every ready job's inputs. On the full run that took about
    half a core while the trainings ran beside it on two cores (README, "Snakemake's own
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
