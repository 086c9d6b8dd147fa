from pathlib import Path

from finray.evaluate.experiments import run_experiment
from finray.logs import log_to

setup = snakemake.params.setup
with log_to(snakemake.log[0]):
    m = run_experiment(
        Path(snakemake.output.metrics).parent, snakemake.input.shards,
        tuple(snakemake.params.size), setup["models"], snakemake.input.baseline,
        conditions=setup["conditions"], group_col=setup["group_col"],
        occlusion_levels={k: tuple(v) for k, v in snakemake.params.occlusion_levels.items()},
        seed=snakemake.params.seed)
    print(m[m["group"] == "all"].to_string(index=False))
