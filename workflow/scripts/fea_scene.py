from pathlib import Path

from finray.fea.errors import SimulationError
from finray.fea.scene import run_scene
from finray.geometry.mesh import TriMesh
from finray.logs import log_to

wc, p = snakemake.wildcards, snakemake.params
cfg = {"fea": p.fea, "finger": p.finger,
       "materials": {wc.material: p.material, p.finger["material"]: p.finger_material}}
failed = None
with log_to(snakemake.log[0]):
    try:
        out = run_scene(cfg, TriMesh.load(snakemake.input.finger),
                        TriMesh.load(snakemake.input.object), wc.material,
                        Path(snakemake.output.result).parent,
                        scene={"scene": f"{wc.object}_{wc.material}_h{wc.height}",
                               "object": wc.object, "material": wc.material,
                               "height_mm": float(wc.height), "split": p.split},
                        vtu=p.fea["write_vtu"], failure_report=p.failure_report)
        print({k: v for k, v in out.items() if k != "solver"})
    except SimulationError as e:  # the report outlives the job (not an output)
        failed = f"{e} (report: {p.failure_report})"
        print(failed)
if failed:
    raise SystemExit(failed)  # one line, no traceback
