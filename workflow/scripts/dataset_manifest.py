from finray.dataset import write_manifest
from finray.logs import log_to

with log_to(snakemake.log[0]):
    df = write_manifest(snakemake.input.shards, snakemake.output.manifest)
    print(df.groupby("split").size())
