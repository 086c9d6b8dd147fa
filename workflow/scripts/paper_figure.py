import json
from pathlib import Path

from finray.benchmarks.speed import fea_seconds_by_material
from finray.evaluate import figures
from finray.logs import log_to

name = snakemake.params.figure
out = snakemake.output.pdf
with log_to(snakemake.log[0]):
    if name == "speed":
        figures.speed_figure(json.loads(Path(snakemake.input.speed).read_text()), out)
    elif name == "annotated":
        figures.annotated_figure(
            snakemake.input.model,
            snakemake.input.render[0],
            snakemake.input.video,
            snakemake.input.ingest,
            out,
            snakemake.params.pitch_deg,
        )
    elif name == "sim2real":
        import pandas as pd

        from finray.sim2real.experiment import sim2real_figure

        sim2real_figure(
            pd.read_csv(snakemake.input.frames),
            json.loads(Path(snakemake.input.summary).read_text()),
            out,
        )
    elif name == "face":
        figures.face_figure(dict(zip(snakemake.params.labels, snakemake.input.heights)), out)
    elif name == "sim2real_rigs":
        import pandas as pd

        from finray.sim2real.rigs import rigs_figure

        rigs_figure(
            pd.read_csv(snakemake.input.csv),
            json.loads(Path(snakemake.input.summary).read_text())["level"],
            out,
        )
    else:
        exp_dir = Path(snakemake.input.metrics).parent
        if name == "shape_generalisation":
            figures.generalisation_figure(
                exp_dir, out, "object", "Shape generalisation: held-out shapes"
            )
        elif name == "material_generalisation":
            fea = fea_seconds_by_material(snakemake.input.fea_summaries)
            net_ms = json.loads(Path(snakemake.input.latency).read_text())["full_ms"]
            figures.material_figure(exp_dir, out, fea, net_ms)
        elif name == "occlusion":
            figures.condition_figure(
                exp_dir,
                out,
                "Occlusion of the held-out shapes",
                "occlusion level",
                example_net="occlusion",
            )
        elif name == "viewpoint":
            figures.condition_figure(
                exp_dir,
                out,
                "Camera pitch: perspective renders of the held-out shapes (two distances)",
                "camera pitch (deg)",
                snakemake.params.usable_nrmse_pct,
                example_net="camera",
            )
        else:
            raise ValueError(f"unknown figure {name}")
