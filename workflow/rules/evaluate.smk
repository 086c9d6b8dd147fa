# Evaluation: the paper's simulation experiments on the held-out splits, each with the
# network(s) and the ridge baseline (results/evaluate/<experiment>/).

from finray.train.config import pitch_geometry

EVALUATE = f"{RESULTS}/evaluate"
EXPERIMENTS = ["shape", "material", "occlusion", "pitch", "viewpoint"]


wildcard_constraints:
    experiment="|".join(EXPERIMENTS),


rule evaluate_baseline:
    input:
        shards=shard_files(splits=["train"], pitch=0.0),
    output:
        model=f"{EVALUATE}/baseline/ridge.npz",
        info=f"{EVALUATE}/baseline/fit.json",
    log:
        f"{RESULTS}/logs/evaluate/baseline.log",
    benchmark:
        f"{RESULTS}/benchmarks/evaluate/baseline.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1600,
        runtime=1,
    params:
        size=config["train"]["input_size"],
        seed=config["evaluate"]["seed"],
    script:
        "../scripts/evaluate_baseline.py"


rule evaluate_experiment:
    input:
        unpack(experiment_inputs),
        baseline=f"{EVALUATE}/baseline/ridge.npz",
    output:
        metrics=f"{EVALUATE}/{{experiment}}/metrics.csv",
        summary=f"{EVALUATE}/{{experiment}}/metrics.json",
        frames=f"{EVALUATE}/{{experiment}}/frames.csv",
        examples=f"{EVALUATE}/{{experiment}}/examples.npz",
        heights=f"{EVALUATE}/{{experiment}}/heights.csv",
        checks=f"{EVALUATE}/{{experiment}}/checks.json",  # pitch: augmentation vs renders
    log:
        f"{RESULTS}/logs/evaluate/{{experiment}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/evaluate/{{experiment}}.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1300,
        runtime=5,
    params:
        size=config["train"]["input_size"],
        setup=experiment_params,
        occlusion_levels=section("dataset", keys=("occlusion_levels",))["occlusion_levels"],
        seed=config["evaluate"]["seed"],
        pitch_geometry=canonical(
            pitch_geometry(
                config["dataset"],
                config["render"],
                config["train"]["input_size"][0],
                config["finger"]["extrusion_mm"],
            )
        ),
    script:
        script_path("evaluate_experiment.py")  # (also run by the seeds study's `use rule`)


rule sim2real_no_context:
    # the no-context heads and calibration: from the simulation alone, every rig's the same
    input:
        model=sim2real_model(),
        sim=shard_files(splits=["train"], pitch=0.0, model=sim2real_model_name(config)),
        sim_test=shard_files(splits=["shape"], pitch=0.0),
    output:
        no_context=f"{EVALUATE}/sim2real/no_context.pt",
    log:
        f"{RESULTS}/logs/evaluate/sim2real_no_context.log",
    benchmark:
        f"{RESULTS}/benchmarks/evaluate/sim2real_no_context.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1100,
        runtime=3,
    params:
        size=config["train"]["input_size"],
        sim2real=no_context_params(),
    script:
        script_path("sim2real_no_context.py")  # (also run by the seeds study's `use rule`)


rule sim2real:
    # Reads the ingested takes (the recording format's shards), never lab: settings; the
    # push per frame (the emulator's truth, as a real rig's axis log) only labels the
    # takes' phases in the report (finray.sim2real.phases).
    input:
        lab=[f"{LAB}/ingest/{t}/shard.npz" for t in lab_takes()],
        motion=[f"{LAB}/{t}/truth/frames.csv" for t in lab_takes()],
        model=sim2real_model(),
        torchscript=sim2real_torchscript(),
        no_context=f"{EVALUATE}/sim2real/no_context.pt",
        rig_prior=rig_prior_input(),
    output:
        metrics=f"{EVALUATE}/sim2real/metrics.csv",
        frames=f"{EVALUATE}/sim2real/frames.csv",
        summary=f"{EVALUATE}/sim2real/summary.json",
        calibrations=f"{EVALUATE}/sim2real/calibrations.json",
        corner=report(
            f"{EVALUATE}/sim2real/corner.pdf",
            caption="../report/sim2real_corner.rst",
            category="Sim-to-real",
        ),
    log:
        f"{RESULTS}/logs/evaluate/sim2real.log",
    benchmark:
        f"{RESULTS}/benchmarks/evaluate/sim2real.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1100,
        runtime=7,
    params:
        size=config["train"]["input_size"],
        sim2real=sim2real_params(),
    script:
        script_path("sim2real.py")  # (also run by the seeds study's `use rule`)


# ------------------------------------------------- training on generated objects
# With generated training objects (config/diverse.yaml): generated.compare_model trained on
# the paper's objects only (<model>_paper_objects) against the same model trained with the
# generated ones, on the shape and material experiments' test sets (shard path).
DIVERSITY_DIR = f"{EVALUATE}/diversity"
DIVERSITY_TESTS = ["shape", "material"]


rule evaluate_diversity:
    input:
        unpack(diversity_inputs),
    output:
        table=f"{DIVERSITY_DIR}/table.csv",
        summary=f"{DIVERSITY_DIR}/summary.json",
        experiments=expand(
            f"{DIVERSITY_DIR}/{{test}}/{{name}}",
            test=DIVERSITY_TESTS,
            name=["metrics.csv", "metrics.json", "frames.csv", "examples.npz"],
        ),
    log:
        f"{RESULTS}/logs/evaluate/diversity.log",
    benchmark:
        f"{RESULTS}/benchmarks/evaluate/diversity.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    # as the shape and material experiments together (47 + 45 s, 0.67 GB RSS each in
    # the paper's run), which score a third model and the camera path besides
    resources:
        mem_mb=1300,
        runtime=5,
    params:
        size=config["train"]["input_size"],
        diversity=diversity_params,
    script:
        "../scripts/evaluate_diversity.py"
