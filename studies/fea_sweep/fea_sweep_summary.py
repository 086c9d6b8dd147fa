import os

from finray.benchmarks.fea_sweep import write_summary
from finray.logs import log_to
from finray.precision import cpu_name

with log_to(snakemake.log[0]):
    df = write_summary(
        snakemake.input.tables,
        snakemake.output.summary,
        snakemake.params.force_cap_N,
        f"{cpu_name()}, {os.cpu_count()} cores",
        snakemake.output.table,
    )
    print(df["outcome"].value_counts().to_string())
