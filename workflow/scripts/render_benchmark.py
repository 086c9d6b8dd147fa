import json

from finray.dataset import DatasetParams
from finray.logs import log_to
from finray.render import RenderParams, benchmark

cfg = snakemake.config
with log_to(snakemake.log[0]):
    out = benchmark(snakemake.input.result, params=RenderParams.from_config(cfg["render"]),
                    dataset_params=DatasetParams.from_config(snakemake.params.dataset),
                    extrusion_mm=cfg["finger"]["extrusion_mm"])
    print(out)
    with open(snakemake.output.json, "w") as f:
        json.dump(out, f, indent=2)
