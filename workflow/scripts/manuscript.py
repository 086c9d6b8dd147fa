from pathlib import Path

from finray.evaluate.manuscript import render_manuscript
from finray.logs import log_to

with log_to(snakemake.log[0]):
    render_manuscript(
        snakemake.input.template,
        snakemake.input.summary,
        snakemake.output.md,
        snakemake.output.html,
        extra={
            "speed_table": Path(snakemake.input.speed_table).read_text(),
            # each study: its figure where it was built, else how to build it
            "studies": snakemake.params.studies,
        },
    )
