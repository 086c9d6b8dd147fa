from pathlib import Path

from finray.fea.scene import rigid_object_cfg, scene_job

wc, p = snakemake.wildcards, snakemake.params
# the lab's objects are rigid (printed PLA against a TPU finger)
failed = scene_job(
    rigid_object_cfg(p.fea, p.finger, p.finger_material),
    snakemake.input.finger,
    snakemake.input.object,
    "rigid",
    Path(snakemake.output.result).parent,
    {
        "scene": f"lab_{wc.object}_h{wc.height}",
        "object": wc.object,
        "material": "rigid",
        "height_mm": float(wc.height),
        "split": "lab",
    },
    snakemake.log[0],
    vtu=False,
    failure_report=p.failure_report,
)
if failed:
    raise SystemExit(failed)
