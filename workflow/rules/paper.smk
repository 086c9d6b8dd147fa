# The paper: figures (paper/figures/<name>.pdf + .png, each buildable on its own), the
# headline numbers (results/summary.json) and the manuscript filled from them.

from finray.evaluate.summary import setup_summary
from finray.paper_reference import paper_reference

PAPER = "paper"
FIGURES = [
    "shape_generalisation",
    "material_generalisation",
    "occlusion",
    "viewpoint",
    "speed",
    "sim2real",
    "annotated",
] + (
    ["sim2real_rigs"] if rig_names() else []
)  # lab.rigs
FIGURES += ["face"] if config["face_heights_mm"].get("shape") else []  # contacts over the face


rule figure_face:
    input:
        heights=list(face_figure_runs().values()),
    output:
        pdf=report(f"{PAPER}/figures/face.pdf", caption="../report/face.rst", category="Paper"),
        png=f"{PAPER}/figures/face.png",
    log:
        f"{RESULTS}/logs/paper/face.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        figure="face",
        labels=list(face_figure_runs()),
    script:
        "../scripts/paper_figure.py"


rule evaluate_speed:
    input:
        fea_scenes=f"{RESULTS}/benchmarks/fea_scenes.csv",
        latency=f"{RESULTS}/benchmarks/inference_latency.json",
        # every benchmarked job of the product has run, so that the count and the
        # span are those of the whole DAG whatever order the scheduler picks (the
        # emulated lab, the rig prior and sim-to-real included)
        stages=[f"{DATASET}/manifest.csv"]
        + expand(f"{TRAIN}/{{model}}/model.ts", model=model_names())
        + expand(f"{EVALUATE}/{{experiment}}/metrics.json", experiment=EXPERIMENTS)
        + [f"{EVALUATE}/baseline/fit.json", f"{RESULTS}/lab/qa.json"]
        + [f"{EVALUATE}/sim2real/summary.json"]
        + ([f"{EVALUATE}/sim2real/rigs/summary.json"] if rig_names() else [])
        + diversity_files(),
        # (with generated training objects: the comparison)
        # the studies' timings where they were built (never a reason to build one)
        studies=built(study_targets()),
    output:
        json=f"{EVALUATE}/speed/speed.json",
        table=f"{EVALUATE}/speed/speed.md",
    log:
        f"{RESULTS}/logs/evaluate/speed.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        benchmarks=lambda w, input: os.path.dirname(input.fea_scenes),
    script:
        "../scripts/evaluate_speed.py"


rule figure_shape_generalisation:
    input:
        metrics=f"{EVALUATE}/shape/metrics.json",
    output:
        pdf=report(
            f"{PAPER}/figures/shape_generalisation.pdf",
            caption="../report/shape.rst",
            category="Paper",
        ),
        png=f"{PAPER}/figures/shape_generalisation.png",
    log:
        f"{RESULTS}/logs/paper/shape_generalisation.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        figure="shape_generalisation",
    script:
        "../scripts/paper_figure.py"


rule figure_material_generalisation:
    input:
        metrics=f"{EVALUATE}/material/metrics.json",
        fea_summaries=fea_files("summary.json", splits=["material"]),
        latency=f"{RESULTS}/benchmarks/inference_latency.json",
    output:
        pdf=report(
            f"{PAPER}/figures/material_generalisation.pdf",
            caption="../report/material.rst",
            category="Paper",
        ),
        png=f"{PAPER}/figures/material_generalisation.png",
    log:
        f"{RESULTS}/logs/paper/material_generalisation.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        figure="material_generalisation",
    script:
        "../scripts/paper_figure.py"


rule figure_occlusion:
    input:
        metrics=f"{EVALUATE}/occlusion/metrics.json",
    output:
        pdf=report(
            f"{PAPER}/figures/occlusion.pdf", caption="../report/occlusion.rst", category="Paper"
        ),
        png=f"{PAPER}/figures/occlusion.png",
    log:
        f"{RESULTS}/logs/paper/occlusion.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        figure="occlusion",
    script:
        "../scripts/paper_figure.py"


rule figure_viewpoint:
    input:
        metrics=f"{EVALUATE}/viewpoint/metrics.json",
    output:
        pdf=report(
            f"{PAPER}/figures/viewpoint.pdf", caption="../report/viewpoint.rst", category="Paper"
        ),
        png=f"{PAPER}/figures/viewpoint.png",
    log:
        f"{RESULTS}/logs/paper/viewpoint.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        figure="viewpoint",
        usable_nrmse_pct=config["evaluate"]["usable_nrmse_pct"],
    script:
        "../scripts/paper_figure.py"


rule figure_annotated:
    # what finray predict --annotate draws: a held-out shape's render, an emulated take
    input:
        model=f"{TRAIN}/{config['benchmarks']['realtime_model']}/model.ts",
        render=viewpoint_indices()[:1],
        video=f"{LAB}/{lab_takes()[0]}/take.mp4",
        ingest=f"{LAB}/ingest/{lab_takes()[0]}/ingest.json",
    output:
        pdf=report(
            f"{PAPER}/figures/annotated.pdf", caption="../report/annotated.rst", category="Paper"
        ),
        png=f"{PAPER}/figures/annotated.png",
    log:
        f"{RESULTS}/logs/paper/annotated.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        figure="annotated",
        pitch_deg=config["benchmarks"]["realtime_pitch_deg"],
    script:
        "../scripts/paper_figure.py"


rule figure_speed:
    input:
        speed=f"{EVALUATE}/speed/speed.json",
    output:
        pdf=report(f"{PAPER}/figures/speed.pdf", caption="../report/speed.rst", category="Paper"),
        png=f"{PAPER}/figures/speed.png",
    log:
        f"{RESULTS}/logs/paper/speed.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        figure="speed",
    script:
        "../scripts/paper_figure.py"


rule figure_sim2real:
    input:
        frames=f"{EVALUATE}/sim2real/frames.csv",
        summary=f"{EVALUATE}/sim2real/summary.json",
    output:
        pdf=report(
            f"{PAPER}/figures/sim2real.pdf", caption="../report/sim2real.rst", category="Paper"
        ),
        png=f"{PAPER}/figures/sim2real.png",
    log:
        f"{RESULTS}/logs/paper/sim2real.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        figure="sim2real",
    script:
        "../scripts/paper_figure.py"


rule summary:
    input:
        experiments=expand(f"{EVALUATE}/{{experiment}}/metrics.json", experiment=EXPERIMENTS),
        baseline=f"{EVALUATE}/baseline/fit.json",
        speed=f"{EVALUATE}/speed/speed.json",
        # the FEA cost study's table where it was built (summary key fea_mesh_study)
        fea_pareto=built([f"{RESULTS}/benchmarks/fea_pareto.csv"]),
        fea_scenes=f"{RESULTS}/benchmarks/fea_scenes.csv",
        histories=expand(f"{TRAIN}/{{model}}/history.json", model=model_names()),
        manifest=f"{DATASET}/manifest.csv",  # the frames behind training vs the FEA states
        lab_qa=f"{RESULTS}/lab/qa.json",
        lab_takes=f"{RESULTS}/lab/qa.csv",
        sim2real=f"{EVALUATE}/sim2real/summary.json",
        # sim-to-real on the drawn emulated rigs (lab.rigs), where there are any
        sim2real_rigs=[f"{EVALUATE}/sim2real/rigs/summary.json"] if rig_names() else [],
        diversity=diversity_files(),  # none unless the config has generated training objects
        spread=manuscript_spread(),  # none unless evaluate.spread.manuscript
    output:
        json=f"{RESULTS}/summary.json",
    log:
        f"{RESULTS}/logs/paper/summary.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        usable_nrmse_pct=config["evaluate"]["usable_nrmse_pct"],
        setup=canonical(setup_summary(config)),
        paper=canonical(paper_reference()["values"]),  # a changed reference value reruns the summary
        lab=section("lab", keys=("as_built", "motion", "camera", "sensor")),  # how the takes were emulated
        evaluate=lambda w, input: os.path.dirname(os.path.dirname(input.experiments[0])),
    script:
        "../scripts/summary.py"


rule manuscript:
    input:
        template=os.path.join(REPO, PAPER, "manuscript.md.j2"),
        summary=f"{RESULTS}/summary.json",
        speed_table=f"{EVALUATE}/speed/speed.md",
        figures=expand(f"{PAPER}/figures/{{name}}.png", name=FIGURES),
        # the studies' results where they were built: shown, else how to build them
        studies=built(study_targets()),
    output:
        md=f"{PAPER}/manuscript.md",
        html=report(
            f"{PAPER}/manuscript.html", caption="../report/manuscript.rst", category="Paper"
        ),
    log:
        f"{RESULTS}/logs/paper/manuscript.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        studies=manuscript_studies(),
    script:
        "../scripts/manuscript.py"
