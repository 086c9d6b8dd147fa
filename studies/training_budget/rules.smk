# The training-budget study (studies/training_budget/README.md; config
# benchmarks.training_budget): every model retrained at each point (train keys that
# differ from the train section, which is the point "default") with each seed, through
# the seeds study's rules (studies/seeds/rules.smk: variants s<seed>_<type>_<point>),
# every experiment and sim-to-real run on each: CPU time per model against every error.
#   snakemake --cores 2 training_budget


rule training_budget:
    input:
        experiments=expand(
            f"{SPREAD}/{{variant}}/{{experiment}}/metrics.json",
            variant=sum(budget_variants().values(), []),
            experiment=variant_experiments(),
        ),
        sim2real=expand(
            f"{SPREAD}/{{variant}}/sim2real/summary.json",
            variant=sum(budget_variants().values(), []),
        ),
        histories=expand(
            f"{SPREAD}/{{variant}}/train/{{model}}/history.json",
            variant=sum(budget_variants().values(), []),
            model=spread_models(),
        ),
        # the training jobs' CPU time (Snakemake's benchmark files, products of spread_train)
        cpu=expand(
            f"{RESULTS}/benchmarks/studies/spread/{{variant}}_train_{{model}}.tsv",
            variant=sum(budget_variants().values(), []),
            model=spread_models(),
        ),
    output:
        json=f"{RESULTS}/benchmarks/training_budget.json",
        table=f"{RESULTS}/benchmarks/training_budget.md",
        csv=f"{RESULTS}/benchmarks/training_budget.csv",
        figure=report(
            f"{RESULTS}/benchmarks/training_budget.png", caption="caption.rst", category="Training"
        ),
    log:
        f"{RESULTS}/logs/spread/training_budget.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        variants=budget_variants(),
        points=canonical({"default": {}} | config["benchmarks"]["training_budget"]["points"]),
    script:
        "training_budget.py"
