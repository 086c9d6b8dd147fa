import json

from finray.evaluate.experiments import fit_baseline
from finray.logs import log_to

with log_to(snakemake.log[0]):
    info = fit_baseline(
        snakemake.input.shards,
        tuple(snakemake.params.size),
        snakemake.output.model,
        snakemake.params.seed,
    )
    print(f"ridge alpha {info['alpha']:g}, training NRMSE {info['train']['nrmse_pct']:.2f} %")
    with open(snakemake.output.info, "w") as f:
        json.dump(info, f, indent=1)
