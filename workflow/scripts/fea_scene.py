from pathlib import Path

from finray.fea.scene import scene_job

wc, p = snakemake.wildcards, snakemake.params
cfg = {
    "fea": p.fea,
    "finger": p.finger,
    "materials": {wc.material: p.material, p.finger["material"]: p.finger_material},
}
failed = scene_job(
    cfg,
    snakemake.input.finger,
    snakemake.input.object,
    wc.material,
    Path(snakemake.output.result).parent,
    {
        "scene": f"{wc.object}_{wc.material}_h{wc.height}",
        "object": wc.object,
        "material": wc.material,
        "height_mm": float(wc.height),
        "split": p.split,
    },
    snakemake.log[0],
    vtu=p.fea["write_vtu"],
    failure_report=p.failure_report,
)
if failed:
    raise SystemExit(failed)  # one line, no traceback
