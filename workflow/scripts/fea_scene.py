from pathlib import Path

from finray.fea.output import run_scene
from finray.geometry.mesh import TriMesh
from finray.logs import log_to

wc, p = snakemake.wildcards, snakemake.params
cfg = {"fea": p.fea, "finger": p.finger,
       "materials": {wc.material: p.material, p.finger["material"]: p.finger_material}}
with log_to(snakemake.log[0]):
    out = run_scene(cfg, TriMesh.load(snakemake.input.finger),
                    TriMesh.load(snakemake.input.object), wc.material,
                    Path(snakemake.output.result).parent,
                    scene={"scene": f"{wc.object}_{wc.material}_h{wc.height}", "object": wc.object,
                           "material": wc.material, "height_mm": float(wc.height),
                           "split": p.split},
                    vtu=p.fea["write_vtu"])
    print({k: v for k, v in out.items() if k != "solver"})
