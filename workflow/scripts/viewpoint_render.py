from pathlib import Path

from finray.logs import log_to
from finray.render import RenderParams
from finray.render.viewpoint import render_viewpoint

p = snakemake.params
with log_to(snakemake.log[0]):
    index = render_viewpoint(
        snakemake.input.result,
        Path(snakemake.output.index).parent,
        p.view,
        p.pitches,
        params=RenderParams.from_config(p.render),
        extrusion_mm=p.extrusion_mm,
        scene=p.scene,
    )
    print(f"{len(index['frames'])} frames in {index['seconds']:.1f} s")
