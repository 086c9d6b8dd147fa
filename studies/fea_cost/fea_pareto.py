from finray.benchmarks.fea import study_config
from finray.benchmarks.fea_pareto import run_time_vs_error
from finray.logs import log_to

p = snakemake.params
b = p.sizes
cfg = study_config(p.fea, p.mesh, p.finger, p.materials, p.placement)
with log_to(snakemake.log[0]):
    table = run_time_vs_error(
        cfg,
        snakemake.output.table,
        snakemake.output.figure,
        snakemake.output.summary,
        reference_size_mm=b["fea_reference_mesh_mm"],
        mesh_p2=b["fea_mesh_sizes_mm"],
        mesh_p1=b["fea_p1_mesh_sizes_mm"],
        arc_chords=b["fea_arc_chord_sizes_mm"],
    )
    print(table.to_string())
