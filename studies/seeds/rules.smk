# The seeds study (studies/seeds/README.md; config evaluate.spread): every model of train.models (or those of
# evaluate.spread.models) trained again for each
# seed of evaluate.spread.seeds and each numeric type of evaluate.spread.types, every
# experiment and sim-to-real run on each such variant, and each headline figure given as
# the default seed's value, mean and range (results/evaluate/spread/). Not in the default
# run: it trains len(seeds) x len(bf16) x 4 models.
#   snakemake --cores 2 seeds
#
# A variant is s<seed>_<type>: type auto (train.bf16: auto, the machine's native type),
# fp32 (false) or bf16 (true). Its models, experiments and sim-to-real live in
# results/evaluate/spread/<variant>/, with the same rules' scripts as the run's own.


wildcard_constraints:
    variant=r"s\d+_(auto|fp32|bf16)(_[A-Za-z0-9]+)?",


localrules:
    seeds,


rule seeds:
    input:
        study_files("seeds"),


rule spread_train:
    input:
        shards=train_shards,
        init=model_init,  # the weights it starts from (train.models.<model>.start_from)
    output:
        model=f"{SPREAD}/{{variant}}/train/{{model}}/model.pt",
        torchscript=f"{SPREAD}/{{variant}}/train/{{model}}/model.ts",
        settings=f"{SPREAD}/{{variant}}/train/{{model}}/model.ts.json",
        onnx=f"{SPREAD}/{{variant}}/train/{{model}}/model.onnx",
        onnx_force=f"{SPREAD}/{{variant}}/train/{{model}}/model.force.onnx",
        history=f"{SPREAD}/{{variant}}/train/{{model}}/history.json",
        curves=f"{SPREAD}/{{variant}}/train/{{model}}/curves.png",
    log:
        f"{RESULTS}/logs/studies/spread/{{variant}}_train_{{model}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/spread/{{variant}}_train_{{model}}.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2600,
        runtime=60,
    params:
        train=spread_train_params,
        augment=model_augment,
        dataset=section(
            "dataset",
            keys=SEGMENT_KEYS + ("crop_x_mm", "crop_y_mm", "occlusion_levels", "base_band"),
        ),
        render=section("render", keys=("window_y_mm",)),
        finger=section("finger", keys=("extrusion_mm", "base_width_mm")),
        diagnostics=True,  # validation with training's running batch-norm averages too
    script:
        "../../workflow/scripts/train_model.py"


use rule evaluate_experiment as spread_experiment with:
    output:
        metrics=f"{SPREAD}/{{variant}}/{{experiment}}/metrics.csv",
        summary=f"{SPREAD}/{{variant}}/{{experiment}}/metrics.json",
        frames=f"{SPREAD}/{{variant}}/{{experiment}}/frames.csv",
        examples=f"{SPREAD}/{{variant}}/{{experiment}}/examples.npz",
        heights=f"{SPREAD}/{{variant}}/{{experiment}}/heights.csv",
        checks=f"{SPREAD}/{{variant}}/{{experiment}}/checks.json",
    log:
        f"{RESULTS}/logs/studies/spread/{{variant}}_experiment_{{experiment}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/spread/{{variant}}_experiment_{{experiment}}.tsv"


use rule sim2real_no_context as spread_sim2real_no_context with:
    input:
        model=lambda w: sim2real_model(train_dir(w)),
        sim=shard_files(splits=["train"], pitch=0.0, model=sim2real_model_name(config)),
        sim_test=shard_files(splits=["shape"], pitch=0.0),
    output:
        no_context=f"{SPREAD}/{{variant}}/sim2real/no_context.pt",
    log:
        f"{RESULTS}/logs/studies/spread/{{variant}}_sim2real_no_context.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/spread/{{variant}}_sim2real_no_context.tsv"


use rule sim2real as spread_sim2real with:
    input:
        lab=[f"{LAB}/ingest/{t}/shard.npz" for t in lab_takes()],
        motion=[f"{LAB}/{t}/truth/frames.csv" for t in lab_takes()],
        model=lambda w: sim2real_model(train_dir(w)),
        torchscript=lambda w: sim2real_torchscript(train_dir(w)),
        no_context=f"{SPREAD}/{{variant}}/sim2real/no_context.pt",
        rig_prior=rig_prior_input(),
    output:
        metrics=f"{SPREAD}/{{variant}}/sim2real/metrics.csv",
        frames=f"{SPREAD}/{{variant}}/sim2real/frames.csv",
        summary=f"{SPREAD}/{{variant}}/sim2real/summary.json",
        calibrations=f"{SPREAD}/{{variant}}/sim2real/calibrations.json",
        corner=f"{SPREAD}/{{variant}}/sim2real/corner.pdf",
    log:
        f"{RESULTS}/logs/studies/spread/{{variant}}_sim2real.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/spread/{{variant}}_sim2real.tsv"


use rule rig_sim2real as spread_rig_sim2real with:
    # the variant's heads and calibration on each drawn rig's takes (lab.rigs)
    input:
        lab=lambda w: [f"{RIGS}/{w.rig}/ingest/{t}/shard.npz" for t in lab_takes(rig_lab(w.rig))],
        motion=lambda w: [f"{RIGS}/{w.rig}/{t}/truth/frames.csv" for t in lab_takes(rig_lab(w.rig))],
        model=lambda w: sim2real_model(train_dir(w)),
        torchscript=lambda w: sim2real_torchscript(train_dir(w)),
        no_context=f"{SPREAD}/{{variant}}/sim2real/no_context.pt",
        rig_prior=rig_prior_input(),
    output:
        metrics=f"{SPREAD}/{{variant}}/sim2real/rigs/{{rig}}/metrics.csv",
        frames=f"{SPREAD}/{{variant}}/sim2real/rigs/{{rig}}/frames.csv",
        summary=f"{SPREAD}/{{variant}}/sim2real/rigs/{{rig}}/summary.json",
        calibrations=f"{SPREAD}/{{variant}}/sim2real/rigs/{{rig}}/calibrations.json",
        corner=f"{SPREAD}/{{variant}}/sim2real/rigs/{{rig}}/corner.pdf",
    log:
        f"{RESULTS}/logs/studies/spread/{{variant}}_sim2real_{{rig}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/spread/{{variant}}_sim2real_{{rig}}.tsv"


use rule sim2real_rigs as spread_sim2real_rigs with:
    # the variant's figures on every rig: the configured one and the drawn ones
    input:
        default=f"{SPREAD}/{{variant}}/sim2real/summary.json",
        rigs=expand(f"{SPREAD}/{{{{variant}}}}/sim2real/rigs/{{rig}}/summary.json", rig=rig_names()),
    output:
        json=f"{SPREAD}/{{variant}}/sim2real/rigs/summary.json",
        table=f"{SPREAD}/{{variant}}/sim2real/rigs/rigs.md",
        csv=f"{SPREAD}/{{variant}}/sim2real/rigs/rigs.csv",
        figure=f"{SPREAD}/{{variant}}/sim2real/rigs/rigs.png",
        phases=f"{SPREAD}/{{variant}}/sim2real/rigs/rigs_phases.png",
    log:
        f"{RESULTS}/logs/spread/{{variant}}/sim2real_rigs.log",


rule spread_rigs:
    # sim-to-real on every emulated rig over the variants: the camera model's spread
    # there (a target of its own: it needs no other model, so that the rigs' spread can
    # be measured without retraining every model of the study)
    input:
        rigs=expand(f"{SPREAD}/{{variant}}/sim2real/rigs/summary.json", variant=spread_variants()),
    output:
        json=f"{SPREAD}/rigs/summary.json",
        table=f"{SPREAD}/rigs/rigs.md",
        csv=f"{SPREAD}/rigs/rigs.csv",
        figure=report(f"{SPREAD}/rigs/rigs.png", caption="caption_rigs.rst", category="Sim-to-real"),
    log:
        f"{RESULTS}/logs/spread/rigs.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=2,
    params:
        variants=spread_variants(),
        default=spread_variant(config["train"]["seed"], config["train"]["bf16"]),
    script:
        "spread_rigs.py"


rule spread_summary:
    input:
        experiments=expand(
            f"{SPREAD}/{{variant}}/{{experiment}}/metrics.json",
            variant=spread_variants(),
            experiment=variant_experiments(),
        ),
        sim2real=expand(f"{SPREAD}/{{variant}}/sim2real/summary.json", variant=spread_variants()),
        histories=expand(
            f"{SPREAD}/{{variant}}/train/{{model}}/history.json",
            variant=spread_variants(),
            model=spread_models(),
        ),
    output:
        json=f"{SPREAD}/summary.json",
        table=f"{SPREAD}/spread.md",
        csv=f"{SPREAD}/spread.csv",
        figure=report(f"{SPREAD}/spread.png", caption="caption.rst", category="Training"),
    log:
        f"{RESULTS}/logs/spread/summary.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        variants=spread_variants(),
        # the variant that is the run's own set-up (its seed and numeric type)
        default=spread_variant(config["train"]["seed"], config["train"]["bf16"]),
    script:
        "spread_summary.py"
