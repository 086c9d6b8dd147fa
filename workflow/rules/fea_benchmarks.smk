# FEA stage benchmarks: cost against accuracy (Pareto) and robustness of hard scenes.
# Pure compute from the config (no input files): the params carry the config sections
# the studies read, so that editing them re-runs the studies.


rule fea_pareto:
    output:
        table=f"{RESULTS}/benchmarks/fea_pareto.csv",
        figure=report(
            f"{RESULTS}/benchmarks/fea_pareto.png",
            caption="../report/fea_pareto.rst",
            category="FEA",
        ),
        summary=f"{RESULTS}/benchmarks/fea_pareto.md",
    params:
        fea=config["fea"],
        mesh=config["mesh"],
        finger=config["finger"],
        materials=config["materials"],
        placement=config["placement"],
        sizes=config["benchmarks"],
    log:
        f"{RESULTS}/logs/fea/benchmark_pareto.log",
    benchmark:
        f"{RESULTS}/benchmarks/fea/benchmark_pareto.tsv"
    threads: 1
    resources:
        runtime=20,
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/fea_pareto.py"


rule fea_stability:
    output:
        table=f"{RESULTS}/benchmarks/fea_stability.csv",
        summary=f"{RESULTS}/benchmarks/fea_stability.md",
    params:
        fea=config["fea"],
        mesh=config["mesh"],
        finger=config["finger"],
        materials=config["materials"],
        placement=config["placement"],
        sizes=config["benchmarks"],
    log:
        f"{RESULTS}/logs/fea/benchmark_stability.log",
    benchmark:
        f"{RESULTS}/benchmarks/fea/benchmark_stability.tsv"
    threads: 1
    resources:
        runtime=20,
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/fea_stability.py"
