from finray.evaluate.spread import variant_figures, variant_runs, write_spread
from finray.logs import log_to

inp, out = snakemake.input, snakemake.output
with log_to(snakemake.log[0]):
    done = {
        v: variant_figures(v, inp.experiments, inp.sim2real, inp.histories)
        for v in snakemake.params.variants
    }  # results/evaluate/spread/<variant>/...
    table = write_spread(
        {v: f for v, (f, _) in done.items()},
        snakemake.params.default,
        out,
        runs={v: variant_runs(h) for v, (_, h) in done.items()},
    )
    print(table.iloc[:, :6].to_string())
