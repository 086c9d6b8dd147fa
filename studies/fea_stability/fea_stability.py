from finray.benchmarks.fea import study_config
from finray.benchmarks.fea_stability import stability_cases, stability_suite
from finray.logs import log_to

p = snakemake.params
b = p.sizes
cfg = study_config(p.fea, p.mesh, p.finger, p.materials, p.placement)
with log_to(snakemake.log[0]):
    cases = stability_cases(b["fea_coarse_mesh_mm"], b["fea_fine_mesh_mm"])
    table = stability_suite(
        cfg, snakemake.output.table, snakemake.output.summary, cases, mesh_size_mm=p.mesh["size_mm"]
    )
    print(table.to_string())
