from finray.geometry.build import build_object
from finray.logs import log_to

p, name = snakemake.params, snakemake.wildcards.object
cfg = {"finger": p.finger, "mesh": p.mesh, "placement": p.placement, "objects": {name: p.spec}}
with log_to(snakemake.log[0]):
    obj = build_object(
        cfg,
        name,
        float(snakemake.wildcards.height),
        snakemake.output.npz,
        snakemake.params.deformable,
    )
    print(obj.meta)
