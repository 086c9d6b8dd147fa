import json
from pathlib import Path

from finray.benchmarks.realtime import realtime_report, realtime_table
from finray.logs import log_to
from finray.render.scene import load_render_index

b = snakemake.params.benchmarks
with log_to(snakemake.log[0]):
    # one held-out shape's viewpoint renders at one pitch, in push order
    folder = Path(snakemake.input.renders[0]).parent
    frames = sorted(
        (
            f
            for f in load_render_index(folder)["frames"]
            if f["pitch_deg"] == b["realtime_pitch_deg"]
        ),
        key=lambda f: (f["distance_mm"], f["frame"]),
    )
    out = realtime_report(
        snakemake.input.model,
        [folder / f["image"] for f in frames],
        snakemake.params.work,
        sizes=[tuple(s) for s in b["realtime_sizes"]],
        seconds=b["realtime_seconds"],
        forces_N=[f["fx_N"] for f in frames],
    )
    Path(snakemake.output.json).write_text(json.dumps(out, indent=1))
    Path(snakemake.output.table).write_text(realtime_table(out))
