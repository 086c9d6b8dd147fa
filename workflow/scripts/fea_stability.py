from finray.fea.studies import CIRCLE_D20, stability_cases, stability_suite
from finray.logs import log_to

p = snakemake.params
b = p.sizes
# the sections the suite reads; it validates a whole config, so it gets its own object
cfg = {"fea": p.fea, "mesh": p.mesh, "finger": p.finger, "materials": p.materials,
       "placement": p.placement, "objects": {"circle_d20": CIRCLE_D20}}
with log_to(snakemake.log[0]):
    cases = stability_cases(b["fea_coarse_mesh_mm"], b["fea_fine_mesh_mm"])
    table = stability_suite(cfg, snakemake.output.table, snakemake.output.summary,
                            cases, mesh_size_mm=p.mesh["size_mm"])
    print(table.to_string())
