from pathlib import Path

from finray.logs import log_to
from finray.render import RenderParams, render_scene

cfg = snakemake.config
with log_to(snakemake.log[0]):
    index = render_scene(snakemake.input.result, Path(snakemake.output.index).parent,
                         float(snakemake.wildcards.pitch),
                         params=RenderParams.from_config(cfg["render"]),
                         extrusion_mm=cfg["finger"]["extrusion_mm"], scene=snakemake.params.scene)
    print(f"{index['n_frames']} frames with {index['renderer']} in {index['seconds']:.1f} s")
