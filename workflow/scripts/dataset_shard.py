from pathlib import Path

from finray.dataset import DatasetParams, build_shard
from finray.logs import log_to

with log_to(snakemake.log[0]):
    meta = build_shard(Path(snakemake.input.index).parent, snakemake.output.shard,
                       scene=snakemake.params.scene,
                       params=DatasetParams.from_config(snakemake.config["dataset"]))
    print(meta["scene"], meta["n_frames"])
