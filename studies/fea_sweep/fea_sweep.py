from finray.benchmarks.fea import study_config
from finray.benchmarks.fea_sweep import draw_scenes, run_scenes
from finray.config import validate_config
from finray.geometry.finger import FingerParams
from finray.logs import log_to

p, wc = snakemake.params, snakemake.wildcards
sweep = p.sweep["fea_sweep"]
cfg = validate_config(study_config(p.fea, p.mesh, p.finger, p.materials, p.placement))
batch = int(wc.batch)
if batch >= sweep["batches"]:
    raise SystemExit(f"fea sweep: batch {batch} is beyond the {sweep['batches']} batches")
with log_to(snakemake.log[0]):
    scenes = draw_scenes(
        sweep["count"],
        sweep["seed"],
        sweep,
        FingerParams.from_config(cfg["finger"]),
        cfg["mesh"]["size_mm"],
    )
    table = run_scenes(cfg, scenes[batch :: sweep["batches"]])
    table.to_csv(snakemake.output.table, index=False, float_format="%.6g")
