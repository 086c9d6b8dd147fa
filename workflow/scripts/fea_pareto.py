from finray.fea.studies import run_time_vs_error
from finray.logs import log_to

b = snakemake.config["benchmarks"]
with log_to(snakemake.log[0]):
    table = run_time_vs_error(snakemake.config, snakemake.output.table,
                              snakemake.output.figure, snakemake.output.summary,
                              reference_size_mm=b["fea_reference_mesh_mm"],
                              mesh_p2=b["fea_mesh_sizes_mm"], mesh_p1=b["fea_p1_mesh_sizes_mm"],
                              arc_chords=b["fea_arc_chord_sizes_mm"])
    print(table.to_string())
