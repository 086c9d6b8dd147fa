from finray.benchmarks.network import train_time_table
from finray.logs import log_to

with log_to(snakemake.log[0]):
    table = train_time_table(
        snakemake.params.models, snakemake.input.histories, snakemake.input.benchmarks
    )
    table.to_csv(snakemake.output.table, index=False, float_format="%.6g")
    print(table.to_string())
