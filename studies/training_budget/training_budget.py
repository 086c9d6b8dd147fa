from pathlib import Path

from finray.benchmarks.budget import cpu_seconds, write_budget
from finray.evaluate.spread import variant_figures
from finray.logs import log_to

inp, out = snakemake.input, snakemake.output
with log_to(snakemake.log[0]):
    figures, cpu, cpu_names = {}, {}, set()
    for point, variants in snakemake.params.variants.items():  # results/evaluate/spread/<variant>/
        for v in variants:
            figures.setdefault(point, {})[v], hist = variant_figures(
                v, inp.experiments, inp.sim2real, inp.histories
            )
            cpu_names |= {h["cpu"] for h in hist.values()}
            cpu.setdefault(point, {})[v] = {
                Path(p).stem.split("_train_")[1]: cpu_seconds(p)
                for p in inp.cpu
                if Path(p).stem.startswith(f"{v}_train_")
            }
    table = write_budget(figures, cpu, snakemake.params.points, out, ", ".join(sorted(cpu_names)))
    print(table.to_string())
