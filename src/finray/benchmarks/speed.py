"""Speed: FEA seconds per scene against network milliseconds per frame, the pipeline's
time per stage and the studies' times from Snakemake's benchmark files (``benchmark:``
of each rule: ``results/benchmarks/<stage>/`` for the pipeline, ``.../studies/`` for the
studies), and the DAG's wall time."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from .timing import job_cpu_s
from ..paper_reference import paper_value


def fea_seconds(fea_scenes_csv) -> dict[str, dict]:
    """Wall time of the FEA scenes (one thread each) per material: median, mean, max, n."""
    df = pd.read_csv(fea_scenes_csv)
    out = {}
    for mat, g in df.groupby("material", sort=True):
        t = g["wall_time_s"]
        out[str(mat)] = {
            "median": float(t.median()),
            "mean": float(t.mean()),
            "max": float(t.max()),
            "n": int(len(t)),
            "newton_iterations_median": float(g["newton_iterations"].median()),
        }
    return out


def fea_seconds_by_material(summary_paths) -> dict[str, float]:
    """Median FEA wall time (s) per material from the scenes' ``summary.json``
    (``results/fea/<object>/<material>/h<h>/summary.json``): the material figure needs
    the ring's scenes only, not the whole batch's ``fea_scenes.csv``."""
    times: dict[str, list] = {}
    for p in summary_paths:
        s = json.loads(Path(p).read_text())
        times.setdefault(Path(p).parent.parent.name, []).append(float(s["wall_time_s"]))
    return {m: float(np.median(v)) for m, v in sorted(times.items())}


STAGE_ORDER = ["geometry", "fea", "render", "dataset", "train", "evaluate"]
#: Sub-folder of the benchmark files of the studies (``studies/<name>/``, each built by
#: its own target, not by the default run: their files are there where a study was
#: built) and of the inference-latency job: not stages of the pipeline, so they are
#: reported apart.
STUDIES = "studies"
#: What :func:`dag_span` measures, in words (it goes into speed.json).
DAG_SPAN_COVERS = (
    "from the start of the first benchmarked job to the end of the last one (the speed "
    "job's inputs): job end = the mtime of its Snakemake benchmark file, start = end - "
    "its wall seconds. Jobs without a benchmark file (figures, manifest, reports) are "
    "not counted; after a partial rerun the span reaches back to the oldest job whose "
    "result was kept."
)


def _jobs(files) -> pd.DataFrame:
    """One row per Snakemake benchmark file: wall ``s``, ``cpu_time`` (s; the job's own
    figure from its log where there is one, ``cpu_from_log``: :func:`~.timing.job_cpu_s`),
    ``end`` (its mtime, epoch s) and ``start`` (= end - s). A file with repeats counts as
    one job (its rows summed)."""
    rows = []
    for f in files:
        t = pd.read_csv(f, sep="\t")
        end = Path(f).stat().st_mtime
        s = float(t["s"].sum())
        cpu, own = job_cpu_s(f)
        rows.append(
            {
                "file": str(f),
                "s": s,
                "cpu_time": cpu,
                "cpu_from_log": own,
                "end": end,
                "start": end - s,
            }
        )
    return pd.DataFrame(rows, columns=["file", "s", "cpu_time", "cpu_from_log", "end", "start"])


def _totals(jobs: pd.DataFrame) -> dict:
    return {
        "jobs": int(len(jobs)),
        "wall_s": float(jobs["s"].sum()),
        "cpu_s": float(jobs["cpu_time"].sum()),
        "longest_job_s": float(jobs["s"].max()),
    }


def _stage_dirs(benchmark_dir) -> list[Path]:
    rank = {n: i for i, n in enumerate(STAGE_ORDER)}
    dirs = [p for p in Path(benchmark_dir).iterdir() if p.is_dir() and p.name != STUDIES]
    return sorted(dirs, key=lambda p: (rank.get(p.name, len(rank)), p.name))


def _stage_files(stage_dir: Path) -> list[Path]:
    """A stage's benchmark files, those of its sub-folders too (the drawn rigs'
    ``lab/rigs/<rig>/``, the rig prior's ``evaluate/rig_prior/``): left out, their jobs'
    time counted as idle cores."""
    return sorted(stage_dir.rglob("*.tsv"))


def stage_times(benchmark_dir) -> dict[str, dict]:
    """Per pipeline stage (sub-folder of ``benchmark_dir`` with its own sub-folders, in
    pipeline order; not ``studies/``): jobs, summed wall s, summed CPU s and the longest
    job (s), from the ``.tsv`` files Snakemake writes (``benchmark:`` of each rule) and
    the jobs' logs (their CPU time, :func:`_jobs`)."""
    out = {}
    for d in _stage_dirs(benchmark_dir):
        files = _stage_files(d)
        if files:
            out[d.name] = _totals(_jobs(files))
    return out


def study_times(benchmark_dir) -> dict[str, dict]:
    """Per study (``benchmark_dir/studies/<name>.tsv``): wall s, CPU s (one job each)."""
    files = sorted((Path(benchmark_dir) / STUDIES).glob("*.tsv"))
    return {
        Path(r.file).stem: {"wall_s": r.s, "cpu_s": r.cpu_time} for r in _jobs(files).itertuples()
    }


def dag_span(benchmark_dir) -> dict:
    """Wall time of the DAG from the benchmark files (see :data:`DAG_SPAN_COVERS`):
    ``wall_s`` over every benchmarked job (stages and studies), ``pipeline_wall_s``
    over the stages only, ``job_s``: the sum of the jobs' wall times (``job_s /
    wall_s``: the jobs running at once, on average).

    Why the files and not ``.snakemake/log``: the speed job runs inside the DAG, so
    the log of its own invocation is unfinished, and a DAG built in several
    invocations (a figure, then the rest) has several logs; every kept result has
    its benchmark file."""
    stages = [f for d in _stage_dirs(benchmark_dir) for f in _stage_files(d)]
    studies = sorted((Path(benchmark_dir) / STUDIES).glob("*.tsv"))
    pipe, every = _jobs(stages), _jobs(stages + studies)

    def span(j):
        return float(j["end"].max() - j["start"].min()) if len(j) else float("nan")

    return {
        "wall_s": span(every),
        "pipeline_wall_s": span(pipe),
        "jobs": int(len(every)),
        "job_s": float(every["s"].sum()),
        "job_cpu_s": float(every["cpu_time"].sum()),
        # the jobs whose CPU time is their own (their log's last line), not Snakemake's sample
        "jobs_cpu_from_log": int(every["cpu_from_log"].sum()),
        "idle_core_s": idle_core_s(every, DAG_CORES),
        "cores": DAG_CORES,
        "covers": DAG_SPAN_COVERS,
    }


#: The cores of the README's main command (``snakemake --cores 2``): the idle core-time
#: is counted against them.
DAG_CORES = 2


def idle_core_s(jobs: pd.DataFrame, cores: int = DAG_CORES) -> float:
    """Core-seconds left idle over the DAG's span: the integral of ``max(0, cores -
    jobs running)`` from the first job's start to the last one's end (a core waiting
    on a job that had not started, or on a long job at the end)."""
    if not len(jobs):
        return float("nan")
    t = np.concatenate([jobs["start"].to_numpy(), jobs["end"].to_numpy()])
    step = np.concatenate([np.ones(len(jobs)), -np.ones(len(jobs))])
    order = np.lexsort((step, t))  # at a tie, an end before a start
    t, running = t[order], np.cumsum(step[order])
    return float(np.sum(np.maximum(0.0, cores - running[:-1]) * np.diff(t)))


def speed_summary(fea_scenes_csv, latency_json, benchmark_dir) -> dict:
    lat = json.loads(Path(latency_json).read_text())
    scenes = pd.read_csv(fea_scenes_csv)
    return {
        "fea_seconds_per_scene": fea_seconds(fea_scenes_csv),
        "fea_scenes": {
            "n": int(len(scenes)),
            "converged": int(scenes["converged"].sum()),
            "min_gap_mm": float(scenes["min_gap_mm"].min()),
        },
        "network_ms_per_frame": float(lat["full_ms"]),  # force and stress map
        "network_force_only_ms_per_frame": float(lat["force_ms"]),
        "network_latency": lat,
        "paper_network_ms_per_frame": paper_value("network_ms_per_frame_gpu"),
        "stages": stage_times(benchmark_dir),  # the pipeline only
        "studies": study_times(benchmark_dir),
        "dag": dag_span(benchmark_dir),
    }


def speed_table(speed: dict) -> str:
    """Markdown table of the FEA and network times, the studies' times and the DAG's
    wall time."""
    rows = ["| what | time | note |", "|---|--:|---|"]
    for mat, v in speed["fea_seconds_per_scene"].items():
        rows.append(
            f"| FEA, {mat} object | {v['median']:.1f} s/scene (median of {v['n']}) | "
            "the whole push, one thread |"
        )
    rows.append(
        f"| CNN, raw frame to force and stress map | {speed['network_ms_per_frame']:.2f} ms/frame | "
        "batch 1, one CPU thread, incl. segmentation and crop (median) |"
    )
    rows.append(
        f"| CNN, raw frame to force only | {speed['network_force_only_ms_per_frame']:.2f} ms/frame | "
        "the control-loop path: no stress decoder |"
    )
    rows.append(
        f"| CNN in the paper | {speed['paper_network_ms_per_frame']:.0f} ms/frame | on a GPU, as the paper states it |"
    )
    for name, v in speed["studies"].items():
        rows.append(
            f"| study: {name} | {v['wall_s'] / 60:.1f} min | one job, not a pipeline stage |"
        )
    dag = speed["dag"]
    if np.isfinite(dag["wall_s"]):
        rows.append(
            f"| whole DAG, wall | {dag['wall_s'] / 60:.1f} min | {dag['jobs']} benchmarked "
            f"jobs, {dag['job_s'] / 60:.1f} min of job time; pipeline stages alone "
            f"{dag['pipeline_wall_s'] / 60:.1f} min |"
        )
        if np.isfinite(dag.get("idle_core_s") or np.nan):
            rows.append(
                f"| idle core-time | {dag['idle_core_s'] / 60:.1f} min | of {dag['cores']} "
                f"cores over the DAG's wall time ({100 * dag['idle_core_s'] / (dag['cores'] * dag['wall_s']):.0f} %); "
                f"{dag['job_cpu_s'] / 60:.1f} min of job CPU time |"
            )
    return "\n".join(rows)
