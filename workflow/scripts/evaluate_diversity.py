from pathlib import Path

from finray.evaluate.diversity import GENERATED, PAPER, run_diversity
from finray.logs import log_to

i, d = snakemake.input, snakemake.params.diversity
with log_to(snakemake.log[0]):
    tests = {t: {"shards": list(i[f"{t}_shards"]), "group_col": g} for t, g in d["tests"].items()}
    run_diversity(
        Path(snakemake.output.summary).parent,
        tests,
        snakemake.params.size,
        dict(zip((PAPER, GENERATED), i.models)),
        dict(zip((PAPER, GENERATED), i.histories)),
        d["setup"],
    )
