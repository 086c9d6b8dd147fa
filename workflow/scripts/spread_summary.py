from finray.evaluate.spread import variant_figures, write_spread
from finray.logs import log_to

inp, out = snakemake.input, snakemake.output
with log_to(snakemake.log[0]):
    figures = {v: variant_figures(v, inp.experiments, inp.sim2real, inp.histories)[0]
               for v in snakemake.params.variants}  # results/evaluate/spread/<variant>/...
    table = write_spread(figures, snakemake.params.default, out)
    print(table.iloc[:, :6].to_string())
