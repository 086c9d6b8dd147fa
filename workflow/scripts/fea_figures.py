from finray.fea.figures import force_displacement_figure, jamming_figure, scene_table
from finray.logs import log_to

with log_to(snakemake.log[0]):
    table = scene_table(snakemake.input.summaries, snakemake.output.table)
    force_displacement_figure(
        snakemake.input.results,
        snakemake.input.summaries,
        snakemake.output.curves,
        snakemake.output.curves_png,
    )
    jamming_figure(snakemake.input.results, snakemake.input.summaries, snakemake.output.jamming)
    print(table.describe())
