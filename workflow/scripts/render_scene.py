from pathlib import Path

from finray.dataset import DatasetParams, render_shard
from finray.logs import log_to
from finray.render import RenderParams
from finray.render.camera_views import CameraViews

p = snakemake.params
with log_to(snakemake.log[0]):
    meta = render_shard(
        snakemake.input.result,
        Path(snakemake.output.index).parent,
        snakemake.output.shard,
        float(snakemake.wildcards.pitch),
        render_params=RenderParams.from_config(p.render),
        params=DatasetParams.from_config(p.dataset),
        extrusion_mm=p.extrusion_mm,
        scene=p.scene,
        camera_views=CameraViews.from_config(p.camera_views),
        base_width_mm=p.base_width_mm,
    )
    print(f"{meta['scene']['scene_id']}: {meta['n_frames']} frames with {meta['renderer']}")
