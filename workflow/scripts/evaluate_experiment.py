from pathlib import Path

import json

from finray.evaluate.experiments import pitch_augmentation_iou, run_experiment, run_viewpoint
from finray.logs import log_to

setup, exp = snakemake.params.setup, snakemake.wildcards.experiment
out_dir = Path(snakemake.output.metrics).parent
models = dict(zip(setup["models"], snakemake.input.models))
with log_to(snakemake.log[0]):
    if exp == "viewpoint":  # perspective renders through the predictor
        m = run_viewpoint(
            out_dir,
            snakemake.input.renders,
            snakemake.input.shards,
            tuple(snakemake.params.size),
            models,
            snakemake.input.baseline,
        )
    else:
        m = run_experiment(
            out_dir,
            snakemake.input.shards,
            tuple(snakemake.params.size),
            models,
            snakemake.input.baseline,
            conditions=dict(setup["conditions"]) if setup["conditions"] else None,
            group_col=setup["group_col"],
            occlusion_levels={k: tuple(v) for k, v in snakemake.params.occlusion_levels.items()},
            seed=snakemake.params.seed,
            render_indices=list(snakemake.input.renders),
            train_heights_mm=setup["train_heights_mm"],
        )
    print(m[m["group"] == "all"].to_string(index=False))  # shard and camera paths
    checks = {}
    if exp == "pitch":
        # how close the training's pitch augmentation is to the pitched renders
        checks["augmentation_iou"] = pitch_augmentation_iou(
            snakemake.input.shards, tuple(snakemake.params.size), snakemake.params.pitch_geometry
        )
        print(json.dumps(checks, indent=1))
    with open(snakemake.output.checks, "w") as f:
        json.dump(checks, f, indent=1)
