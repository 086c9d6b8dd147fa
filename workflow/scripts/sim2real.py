import torch

from finray.sim2real.phases import shard_phases
from finray.sim2real.experiment import Sim2RealConfig, run_sim2real, write_outputs
from finray.logs import log_to
from finray.train.export import model_settings

inp, out = snakemake.input, snakemake.output
with log_to(snakemake.log[0]):
    torch.set_num_threads(snakemake.threads)
    cfg = Sim2RealConfig.from_params(snakemake.params.sim2real)
    prior = [inp.rig_prior] if isinstance(inp.rig_prior, str) else list(inp.rig_prior)
    if prior:  # the rig prior's gain from the FEA (finray.sim2real.rig_prior)
        cfg = cfg.with_rig_prior(prior[0])
    meta = model_settings(inp.torchscript)  # the training's ranges: near_base as predict flags it
    phases = shard_phases(list(inp.lab), list(inp.get("motion", [])))  # the report's only
    result = run_sim2real(
        inp.model,
        list(inp.lab),
        inp.no_context,
        snakemake.params.size,
        cfg,
        meta=meta,
        phases=phases,
    )
    write_outputs(result, out)
    print(result["metrics"].to_string())
