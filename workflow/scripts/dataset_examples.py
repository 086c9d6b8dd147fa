from pathlib import Path

from finray.dataset import DatasetParams, example_figure
from finray.logs import log_to

with log_to(snakemake.log[0]):
    dirs = {float(Path(p).parent.name[1:]): Path(p).parent for p in snakemake.input.pitch_indices}
    params = DatasetParams.from_config(snakemake.params.dataset)
    for out in (snakemake.output.pdf, snakemake.output.png):
        example_figure(dirs[0.0], out, pitch_dirs=dirs, params=params)
