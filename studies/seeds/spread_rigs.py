import json
from pathlib import Path

from finray.evaluate.spread import write_spread_rigs
from finray.logs import log_to

inp, p = snakemake.input, snakemake.params
with log_to(snakemake.log[0]):
    # results/evaluate/spread/<variant>/sim2real/rigs/summary.json, in the variants' order
    by_variant = {Path(f).parts[-4]: json.loads(Path(f).read_text()) for f in inp.rigs}
    summary = write_spread_rigs({v: by_variant[v] for v in p.variants}, p.default, snakemake.output)
    print(json.dumps(summary["acceptance"], indent=1))
