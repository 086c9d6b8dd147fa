from finray.fea.studies import stability_cases, stability_suite
from finray.logs import log_to

b = snakemake.config["benchmarks"]
with log_to(snakemake.log[0]):
    cases = stability_cases(b["fea_coarse_mesh_mm"], b["fea_fine_mesh_mm"])
    table = stability_suite(snakemake.config, snakemake.output.table, snakemake.output.summary,
                            cases, mesh_size_mm=snakemake.config["mesh"]["size_mm"])
    print(table.to_string())
