"""Speed: FEA seconds per scene against network milliseconds per frame, and the
pipeline's time per stage from Snakemake's benchmark files (``benchmark:`` of each rule,
written under ``results/benchmarks/<stage>/``)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from finray.paper_reference import paper_value


def fea_seconds(fea_scenes_csv) -> dict[str, dict]:
    """Wall time of the FEA scenes (one thread each) per material: median, mean, max, n."""
    df = pd.read_csv(fea_scenes_csv)
    out = {}
    for mat, g in df.groupby("material", sort=True):
        t = g["wall_time_s"]
        out[str(mat)] = {"median": float(t.median()), "mean": float(t.mean()),
                         "max": float(t.max()), "n": int(len(t)),
                         "newton_iterations_median": float(g["newton_iterations"].median())}
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


def stage_times(benchmark_dir) -> dict[str, dict]:
    """Per stage (sub-folder of ``benchmark_dir``, in pipeline order): jobs, summed wall s,
    summed CPU s and the longest job (s), from the ``.tsv`` files Snakemake writes."""
    out = {}
    dirs = [p for p in Path(benchmark_dir).iterdir() if p.is_dir()]
    rank = {n: i for i, n in enumerate(STAGE_ORDER)}
    for d in sorted(dirs, key=lambda p: (rank.get(p.name, len(rank)), p.name)):
        files = sorted(d.glob("*.tsv"))
        if not files:
            continue
        t = pd.concat([pd.read_csv(f, sep="\t") for f in files], ignore_index=True)
        out[d.name] = {"jobs": len(files), "wall_s": float(t["s"].sum()),
                       "cpu_s": float(t["cpu_time"].sum()), "longest_job_s": float(t["s"].max())}
    return out


def speed_summary(fea_scenes_csv, latency_json, benchmark_dir) -> dict:
    lat = json.loads(Path(latency_json).read_text())
    scenes = pd.read_csv(fea_scenes_csv)
    return {"fea_seconds_per_scene": fea_seconds(fea_scenes_csv),
            "fea_scenes": {"n": int(len(scenes)), "converged": int(scenes["converged"].sum()),
                           "min_gap_mm": float(scenes["min_gap_mm"].min())},
            "network_ms_per_frame": float(lat["full_ms"]),  # force and stress map
            "network_force_only_ms_per_frame": float(lat["force_ms"]),
            "network_latency": lat,
            "paper_network_ms_per_frame": paper_value("network_ms_per_frame_gpu"),
            "stages": stage_times(benchmark_dir)}


def speed_table(speed: dict) -> str:
    """Markdown table of the FEA and network times."""
    rows = ["| what | time | note |", "|---|--:|---|"]
    for mat, v in speed["fea_seconds_per_scene"].items():
        rows.append(f"| FEA, {mat} object | {v['median']:.1f} s/scene (median of {v['n']}) | "
                    f"10 mm push, one thread |")
    rows.append(f"| CNN, raw frame to force and stress map | {speed['network_ms_per_frame']:.2f} ms/frame | "
                "batch 1, one CPU thread, incl. segmentation and crop (median) |")
    rows.append(f"| CNN, raw frame to force only | {speed['network_force_only_ms_per_frame']:.2f} ms/frame | "
                "the control-loop path: no stress decoder |")
    rows.append(f"| CNN in the paper | {speed['paper_network_ms_per_frame']:.0f} ms/frame | desktop GPU |")
    return "\n".join(rows)
