"""Stage times, study times and the DAG's wall time from Snakemake's benchmark files (and
each job's CPU time from its log)."""

import os
import time

import numpy as np
import pytest

from finray.benchmarks.timing import benchmark_log, job_cpu_s
from finray.logs import JOB_CPU, log_to
from finray.logs import job_cpu_s as logged_cpu_s
from finray.benchmarks.speed import DAG_SPAN_COVERS, dag_span, speed_table, stage_times, study_times

HEADER = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"


def _tsv(path, s, cpu, end):
    """A benchmark file of a job that took ``s`` wall seconds and ended at ``end``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(HEADER + f"{s}\t0:00:10\t1\t1\t1\t1\t0\t0\t90\t{cpu}\n")
    os.utime(path, (end, end))


@pytest.fixture()
def bench(tmp_path):
    t0 = 1_700_000_000.0
    _tsv(tmp_path / "geometry" / "finger.tsv", 5.0, 4.0, t0 + 5)  # the first job: 0-5 s
    _tsv(tmp_path / "fea" / "a.tsv", 10.0, 9.5, t0 + 20)  # 10-20 s
    _tsv(tmp_path / "fea" / "b.tsv", 20.0, 19.0, t0 + 30)  # 10-30 s
    _tsv(tmp_path / "train" / "plain.tsv", 100.0, 98.0, t0 + 130)  # the last stage job
    (tmp_path / "empty").mkdir()
    # studies: in the DAG, not stages; the network study ends last
    _tsv(tmp_path / "studies" / "fea_pareto.tsv", 50.0, 49.0, t0 + 60)
    _tsv(tmp_path / "studies" / "train_pareto.tsv", 40.0, 39.0, t0 + 150)
    return tmp_path


def test_stage_times_count_the_pipeline_only(bench):
    t = stage_times(bench)
    assert list(t) == ["geometry", "fea", "train"]  # pipeline order; no studies, no empty
    assert t["fea"] == {"jobs": 2, "wall_s": 30.0, "cpu_s": 28.5, "longest_job_s": 20.0}
    assert t["train"]["wall_s"] == 100.0


def test_study_times_are_apart(bench):
    assert study_times(bench) == {
        "fea_pareto": {"wall_s": 50.0, "cpu_s": 49.0},
        "train_pareto": {"wall_s": 40.0, "cpu_s": 39.0},
    }


def test_dag_span_from_the_file_times(bench):
    d = dag_span(bench)
    assert d["wall_s"] == pytest.approx(150.0)  # first start (0 s) to the last end (150 s)
    assert d["pipeline_wall_s"] == pytest.approx(130.0)  # stages only: 0 s to 130 s
    assert d["jobs"] == 6 and d["job_s"] == pytest.approx(225.0)
    assert d["covers"] == DAG_SPAN_COVERS
    # two cores: one idle 0-5 s, both 5-10 s, one 60-110 s (plain alone) and 130-150 s
    assert d["cores"] == 2 and d["idle_core_s"] == pytest.approx(5 + 10 + 50 + 20)
    assert d["job_cpu_s"] == pytest.approx(4.0 + 9.5 + 19.0 + 98.0 + 49.0 + 39.0)


def test_dag_span_without_benchmark_files(tmp_path):
    d = dag_span(tmp_path)
    assert d["jobs"] == 0 and np.isnan(d["wall_s"]) and np.isnan(d["pipeline_wall_s"])
    assert np.isnan(d["idle_core_s"])


def test_speed_table_lists_studies_and_the_dag(bench):
    speed = {
        "fea_seconds_per_scene": {"steel": {"median": 12.0, "n": 3}},
        "network_ms_per_frame": 1.0,
        "network_force_only_ms_per_frame": 0.5,
        "paper_network_ms_per_frame": 8.0,
        "studies": study_times(bench),
        "dag": dag_span(bench),
    }
    md = speed_table(speed)
    assert "| study: fea_pareto | 0.8 min |" in md and "| study: train_pareto | 0.7 min |" in md
    assert (
        "| whole DAG, wall | 2.5 min | 6 benchmarked jobs, 3.8 min of job time; pipeline "
        "stages alone 2.2 min |" in md
    )


def test_speed_figure_shows_stages_and_studies(bench, tmp_path):
    from finray.evaluate.figures import speed_figure

    speed = {
        "fea_seconds_per_scene": {"steel": {"median": 12.0, "n": 3}},
        "network_ms_per_frame": 1.0,
        "stages": stage_times(bench),
        "studies": study_times(bench),
        "dag": dag_span(bench),
    }
    speed_figure(speed, tmp_path / "speed.pdf")
    assert (tmp_path / "speed.pdf").stat().st_size > 0


def test_a_stage_counts_its_sub_folders(bench):
    """The drawn rigs' jobs (lab/rigs/<rig>/) belong to the lab stage and fill the cores:
    left out, their time was counted as idle."""
    t0 = 1_700_000_000.0
    _tsv(bench / "lab" / "take.tsv", 30.0, 29.0, t0 + 90)  # 60-90 s, beside plain
    _tsv(bench / "lab" / "rigs" / "rig1" / "take.tsv", 20.0, 19.0, t0 + 110)  # 90-110 s
    t = stage_times(bench)
    assert t["lab"] == {"jobs": 2, "wall_s": 50.0, "cpu_s": 48.0, "longest_job_s": 30.0}
    d = dag_span(bench)
    assert d["jobs"] == 8 and d["job_cpu_s"] == pytest.approx(218.5 + 48.0)
    # the 60-110 s gap beside plain is filled: idle 0-5 s (one core), 5-10 s (both), 130-150 s (one)
    assert d["idle_core_s"] == pytest.approx(5 + 10 + 20)


def test_a_job_s_cpu_time_is_its_log_s_where_it_has_one(tmp_path):
    """log_to ends a job's log with the process's CPU time; the speed table takes it over
    Snakemake's sampled figure, which reads a long job up to 30 s low."""
    bench = tmp_path / "results" / "benchmarks"
    _tsv(bench / "fea" / "a.tsv", 40.0, 15.0, 1_700_000_040.0)  # sampled: 15 of ~40 s
    _tsv(bench / "fea" / "b.tsv", 10.0, 9.5, 1_700_000_050.0)  # a job without its log
    log = tmp_path / "results" / "logs" / "fea" / "a.log"
    with log_to(log):
        t = time.process_time()
        while time.process_time() - t < 0.2:
            pass
        print("the job's output")
    assert log.read_text().splitlines()[-1].startswith(JOB_CPU)
    assert benchmark_log(bench / "fea" / "a.tsv") == log
    cpu, own = job_cpu_s(bench / "fea" / "a.tsv")
    assert own and cpu >= 0.2 and cpu == logged_cpu_s(log)
    assert job_cpu_s(bench / "fea" / "b.tsv") == (9.5, False)
    assert stage_times(bench)["fea"]["cpu_s"] == pytest.approx(cpu + 9.5)
    assert dag_span(bench)["jobs_cpu_from_log"] == 1
