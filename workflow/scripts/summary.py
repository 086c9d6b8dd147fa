import json
from pathlib import Path

from finray.evaluate.spread import manuscript_spread
from finray.evaluate.summary import build_summary, lab_summary
from finray.logs import log_to

with log_to(snakemake.log[0]):
    experiments = [Path(p).parent.name for p in snakemake.input.experiments]
    histories = {Path(p).parent.name: p for p in snakemake.input.histories}
    s = build_summary(
        snakemake.params.evaluate,
        experiments,
        snakemake.input.baseline,
        snakemake.input.speed,
        # the FEA cost study's table, where it was built (else no fea_mesh_study)
        snakemake.input.fea_pareto[0] if snakemake.input.fea_pareto else None,
        histories,
        snakemake.params.usable_nrmse_pct,
        fea_scenes_csv=snakemake.input.fea_scenes,
        manifest_csv=snakemake.input.manifest,
    )
    s["setup"] = snakemake.params.setup  # the set-up constants, from the config that ran
    s["lab"] = lab_summary(
        snakemake.input.lab_qa, snakemake.input.lab_takes, snakemake.params.lab
    )  # emulated takes, not recordings
    # sim-to-real on the emulated takes, with the calibrated force
    s["sim2real"] = json.loads(Path(snakemake.input.sim2real).read_text())
    for path in snakemake.input.sim2real_rigs:  # the same on the drawn emulated rigs
        s["sim2real_rigs"] = json.loads(Path(path).read_text())
    for path in snakemake.input.diversity:  # training on generated objects (config/diverse.yaml)
        s["diversity"] = json.loads(Path(path).read_text())
    for (
        path
    ) in snakemake.input.spread:  # the spread over seeds and types (evaluate.spread.manuscript)
        s["spread"] = manuscript_spread(json.loads(Path(path).read_text()))
    s["paper"] = (
        snakemake.params.paper
    )  # the paper's reference numbers (finray/paper_reference.yaml)
    with open(snakemake.output.json, "w") as f:
        json.dump(s, f, indent=1)
