import json
from pathlib import Path

from finray.evaluate.budget import cpu_seconds, write_budget
from finray.evaluate.spread import headline_figures
from finray.logs import log_to

inp, out = snakemake.input, snakemake.output
with log_to(snakemake.log[0]):
    figures, cpu, cpu_names = {}, {}, set()
    for point, variants in snakemake.params.variants.items():  # results/evaluate/spread/<variant>/
        for v in variants:
            exps = {Path(p).parent.name: Path(p).parent for p in inp.experiments if f"/{v}/" in p}
            s2r = json.loads(next(Path(p) for p in inp.sim2real if f"/{v}/" in p).read_text())
            hist = {Path(p).parent.name: json.loads(Path(p).read_text())
                    for p in inp.histories if f"/{v}/" in p}
            cpu_names |= {h["cpu"] for h in hist.values()}
            figures.setdefault(point, {})[v] = headline_figures(exps, s2r, hist)
            cpu.setdefault(point, {})[v] = {Path(p).stem.split("_train_")[1]: cpu_seconds(p)
                                            for p in inp.cpu if Path(p).stem.startswith(f"{v}_train_")}
    table = write_budget(figures, cpu, snakemake.params.points, out, ", ".join(sorted(cpu_names)))
    print(table.to_string())
