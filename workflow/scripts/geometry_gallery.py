from finray.geometry.gallery import gallery
from finray.geometry.mesh import TriMesh
from finray.logs import log_to

with log_to(snakemake.log[0]):
    objects = {}
    for path in snakemake.input.objects:
        obj = TriMesh.load(path)
        objects.setdefault(obj.meta["name"], []).append(obj)
    gallery(
        TriMesh.load(snakemake.input.finger),
        objects,
        snakemake.output.pdf,
        snakemake.output.png,
        snakemake.params.splits,
    )
