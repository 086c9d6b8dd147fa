# FEA stage benchmarks: cost against accuracy (Pareto) and robustness of hard scenes.
# Pure compute from the config (no input files): the params carry the config sections
# the studies read, so that editing them re-runs the studies (and nothing else does).

FEA_STUDY_KEYS = ("fea_reference_mesh_mm", "fea_mesh_sizes_mm", "fea_p1_mesh_sizes_mm",
                  "fea_arc_chord_sizes_mm", "fea_fine_mesh_mm", "fea_coarse_mesh_mm")


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
        fea=section("fea"),
        mesh=section("mesh"),
        finger=section("finger"),
        materials=study_materials(),
        placement=section("placement"),
        sizes=section("benchmarks", keys=FEA_STUDY_KEYS),
    log:
        f"{RESULTS}/logs/fea/benchmark_pareto.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/fea_pareto.tsv"
    threads: 1
    resources:
        mem_mb=1400,
        runtime=12,
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/fea_pareto.py"


rule fea_stability:
    output:
        table=f"{RESULTS}/benchmarks/fea_stability.csv",
        summary=f"{RESULTS}/benchmarks/fea_stability.md",
    params:
        fea=section("fea"),
        mesh=section("mesh"),
        finger=section("finger"),
        materials=study_materials("neoprene"),  # a case of the suite
        placement=section("placement"),
        sizes=section("benchmarks", keys=FEA_STUDY_KEYS),
    log:
        f"{RESULTS}/logs/fea/benchmark_stability.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/fea_stability.tsv"
    threads: 1
    resources:
        mem_mb=1200,
        runtime=6,
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/fea_stability.py"


# The sweep over the whole face (not in the default run):
#   snakemake --cores 2 results/benchmarks/fea_sweep/summary.md
rule fea_sweep_batch:
    output:
        table=f"{RESULTS}/benchmarks/fea_sweep/batch_{{batch}}.csv",
    params:
        fea=section("fea"),
        mesh=section("mesh"),
        finger=section("finger"),
        materials=study_materials(),
        placement=section("placement"),
        sweep=section("benchmarks", keys=("fea_sweep",)),
    wildcard_constraints:
        batch=r"\d+",
    log:
        f"{RESULTS}/logs/fea/sweep_batch_{{batch}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/fea_sweep_batch_{{batch}}.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=60,
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/fea_sweep.py"


rule fea_sweep_summary:
    input:
        tables=expand(
            f"{RESULTS}/benchmarks/fea_sweep/batch_{{batch}}.csv",
            batch=range(config["benchmarks"]["fea_sweep"]["batches"]),
        ),
    output:
        summary=f"{RESULTS}/benchmarks/fea_sweep/summary.md",
        table=f"{RESULTS}/benchmarks/fea_sweep/scenes.csv",
    params:
        force_cap_N=config["fea"]["force_cap_N"],
    log:
        f"{RESULTS}/logs/fea/sweep_summary.log",
    threads: 1
    resources:
        mem_mb=500,
        runtime=2,
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/fea_sweep_summary.py"
