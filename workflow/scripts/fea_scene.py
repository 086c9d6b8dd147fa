from pathlib import Path

from finray.fea.output import run_scene
from finray.fea.simulate import SimulationError
from finray.geometry.mesh import TriMesh
from finray.logs import log_to

wc = snakemake.wildcards
failed = None
with log_to(snakemake.log[0]):
    try:
        out = run_scene(snakemake.config, TriMesh.load(snakemake.input.finger),
                        TriMesh.load(snakemake.input.object), wc.material,
                        Path(snakemake.output.result).parent,
                        scene={"scene": f"{wc.object}_{wc.material}_h{wc.height}",
                               "object": wc.object, "material": wc.material,
                               "height_mm": float(wc.height),
                               "split": snakemake.config["objects"][wc.object]["split"]},
                        vtu=snakemake.params.fea["write_vtu"],
                        failure_report=snakemake.params.failure_report)
        print({k: v for k, v in out.items() if k != "solver"})
    except SimulationError as e:  # the report outlives the job (not an output)
        failed = f"{e} (report: {snakemake.params.failure_report})"
        print(failed)
if failed:
    raise SystemExit(failed)  # one line, no traceback
