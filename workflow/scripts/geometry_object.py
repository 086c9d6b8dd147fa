from finray.geometry.build import build_object
from finray.logs import log_to

with log_to(snakemake.log[0]):
    obj = build_object(snakemake.config, snakemake.wildcards.object,
                       float(snakemake.wildcards.height), snakemake.output.npz,
                       snakemake.params.deformable)
    print(obj.meta)
