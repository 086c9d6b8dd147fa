# The print's time dependence (studies/print_time/README.md): sim-to-real with the static
# calibration (no relaxation, no softening: evaluate.sim2real.priors relax and softening
# [0, 0]) beside the default time-dependent one, on the same emulated takes, for the
# run's camera model and each seeds-study variant's (evaluate.spread), per phase of the
# takes. Not in the default run: snakemake --cores 2 print_time

PRINT_TIME = f"{EVALUATE}/print_time"


wildcard_constraints:
    variant=r"run|s\d+_[a-z0-9]+",


use rule sim2real as print_time_static with:
    input:
        lab=[f"{LAB}/ingest/{t}/shard.npz" for t in lab_takes()],
        motion=[f"{LAB}/{t}/truth/frames.csv" for t in lab_takes()],
        model=lambda w: sim2real_model(print_time_train(w)),
        torchscript=lambda w: sim2real_torchscript(print_time_train(w)),
        no_context=lambda w: f"{print_time_dir(w.variant)}/no_context.pt",
        rig_prior=rig_prior_input(),
    output:
        metrics=f"{PRINT_TIME}/{{variant}}/static/default/metrics.csv",
        frames=f"{PRINT_TIME}/{{variant}}/static/default/frames.csv",
        summary=f"{PRINT_TIME}/{{variant}}/static/default/summary.json",
        calibrations=f"{PRINT_TIME}/{{variant}}/static/default/calibrations.json",
        corner=f"{PRINT_TIME}/{{variant}}/static/default/corner.pdf",
    log:
        f"{RESULTS}/logs/studies/print_time/{{variant}}_static_default.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/print_time/{{variant}}_static_default.tsv"
    params:
        size=config["train"]["input_size"],
        sim2real=static_sim2real_params(),


use rule rig_sim2real as print_time_static_rig with:
    input:
        lab=lambda w: [f"{RIGS}/{w.rig}/ingest/{t}/shard.npz" for t in lab_takes(rig_lab(w.rig))],
        motion=lambda w: [f"{RIGS}/{w.rig}/{t}/truth/frames.csv" for t in lab_takes(rig_lab(w.rig))],
        model=lambda w: sim2real_model(print_time_train(w)),
        torchscript=lambda w: sim2real_torchscript(print_time_train(w)),
        no_context=lambda w: f"{print_time_dir(w.variant)}/no_context.pt",
        rig_prior=rig_prior_input(),
    output:
        metrics=f"{PRINT_TIME}/{{variant}}/static/{{rig}}/metrics.csv",
        frames=f"{PRINT_TIME}/{{variant}}/static/{{rig}}/frames.csv",
        summary=f"{PRINT_TIME}/{{variant}}/static/{{rig}}/summary.json",
        calibrations=f"{PRINT_TIME}/{{variant}}/static/{{rig}}/calibrations.json",
        corner=f"{PRINT_TIME}/{{variant}}/static/{{rig}}/corner.pdf",
    log:
        f"{RESULTS}/logs/studies/print_time/{{variant}}_static_{{rig}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/print_time/{{variant}}_static_{{rig}}.tsv"
    params:
        size=config["train"]["input_size"],
        sim2real=static_sim2real_params(),


rule print_time_table:
    # per variant, rig, context count and phase: the time-dependent calibration's
    # NRMSE and coverage beside the static one's
    input:
        dynamic=[
            f"{print_time_dir(v)}/{r}summary.json"
            for v in print_time_variants()
            for r in ["", *(f"rigs/{x}/" for x in rig_names())]
        ],
        static=[
            f"{PRINT_TIME}/{v}/static/{r}/summary.json"
            for v in print_time_variants()
            for r in ["default", *rig_names()]
        ],
    output:
        csv=f"{PRINT_TIME}/phases.csv",
        table=f"{PRINT_TIME}/phases.md",
        json=f"{PRINT_TIME}/summary.json",
        figure=f"{PRINT_TIME}/phases.png",
    log:
        f"{RESULTS}/logs/studies/print_time/table.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=600,
        runtime=2,
    params:
        variants=print_time_variants(),
        rigs=["default", *rig_names()],
    script:
        "table.py"


rule print_time:
    input:
        study_files("print_time"),
