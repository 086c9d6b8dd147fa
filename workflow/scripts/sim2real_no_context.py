import torch

from finray.sim2real.experiment import Sim2RealConfig, fit_no_context, save_no_context
from finray.logs import log_to

inp = snakemake.input
with log_to(snakemake.log[0]):
    torch.set_num_threads(snakemake.threads)
    result = fit_no_context(
        inp.model,
        list(inp.sim),
        list(inp.sim_test),
        snakemake.params.size,
        Sim2RealConfig.from_params(snakemake.params.sim2real),
    )
    save_no_context(result, snakemake.output.no_context)
