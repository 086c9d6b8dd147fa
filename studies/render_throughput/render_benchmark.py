import json

from finray.benchmarks.render import benchmark
from finray.dataset import DatasetParams
from finray.logs import log_to
from finray.render import RenderParams

p = snakemake.params
with log_to(snakemake.log[0]):
    out = benchmark(
        snakemake.input.result,
        params=RenderParams.from_config(p.render),
        dataset_params=DatasetParams.from_config(p.dataset),
        extrusion_mm=p.extrusion_mm,
    )
    print(out)
    with open(snakemake.output.json, "w") as f:
        json.dump(out, f, indent=2)
