from pathlib import Path

from finray.dataset import DatasetParams, render_shard
from finray.logs import log_to
from finray.render import RenderParams

cfg = snakemake.config
with log_to(snakemake.log[0]):
    meta = render_shard(snakemake.input.result, Path(snakemake.output.index).parent,
                        snakemake.output.shard, float(snakemake.wildcards.pitch),
                        render_params=RenderParams.from_config(cfg["render"]),
                        params=DatasetParams.from_config(cfg["dataset"]),
                        extrusion_mm=cfg["finger"]["extrusion_mm"], scene=snakemake.params.scene)
    print(f"{meta['scene']['scene_id']}: {meta['n_frames']} frames with {meta['renderer']}")
