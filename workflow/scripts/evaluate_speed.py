import json

from finray.benchmarks.speed import speed_summary, speed_table
from finray.logs import log_to

with log_to(snakemake.log[0]):
    s = speed_summary(
        snakemake.input.fea_scenes, snakemake.input.latency, snakemake.params.benchmarks
    )
    with open(snakemake.output.json, "w") as f:
        json.dump(s, f, indent=1)
    with open(snakemake.output.table, "w") as f:
        f.write(speed_table(s) + "\n")
    print(speed_table(s))
