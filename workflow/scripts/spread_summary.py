import json
from pathlib import Path

from finray.evaluate.spread import headline_figures, write_spread
from finray.logs import log_to

inp, out = snakemake.input, snakemake.output
with log_to(snakemake.log[0]):
    figures = {}
    for v in snakemake.params.variants:  # results/evaluate/spread/<variant>/...
        exps = {Path(p).parent.name: Path(p).parent for p in inp.experiments if f"/{v}/" in p}
        s2r = json.loads(next(Path(p) for p in inp.sim2real if f"/{v}/" in p).read_text())
        hist = {Path(p).parent.name: json.loads(Path(p).read_text())
                for p in inp.histories if f"/{v}/" in p}
        figures[v] = headline_figures(exps, s2r, hist)
    table = write_spread(figures, snakemake.params.default, out)
    print(table.iloc[:, :6].to_string())
