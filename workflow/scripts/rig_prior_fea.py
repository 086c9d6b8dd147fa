from pathlib import Path

from finray.fea.errors import SimulationError
from finray.fea.scene import run_scene
from finray.geometry.mesh import TriMesh
from finray.logs import log_to

wc, p = snakemake.wildcards, snakemake.params
# a training scene's steel object: rigid
cfg = {"fea": p.fea, "finger": p.finger,
       "materials": {"rigid": {"rigid": True}, p.finger["material"]: p.finger_material}}
failed = None
with log_to(snakemake.log[0]):
    try:
        out = run_scene(cfg, TriMesh.load(snakemake.input.finger), TriMesh.load(snakemake.input.object),
                        "rigid", Path(snakemake.output.result).parent,
                        scene={"scene": f"rig_prior_{wc.variant}_{wc.object}_h{wc.height}",
                               "object": wc.object, "material": "rigid",
                               "height_mm": float(wc.height), "split": "rig_prior"},
                        vtu=False, failure_report=p.failure_report)
        print({k: v for k, v in out.items() if k != "solver"})
    except SimulationError as e:
        failed = f"{e} (report: {p.failure_report})"
        print(failed)
if failed:
    raise SystemExit(failed)
