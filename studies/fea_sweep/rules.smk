# The FEA sweep over the whole face (studies/fea_sweep/README.md): seeded steel scenes
# from the lowest height the geometry allows to benchmarks.fea_sweep.height_max_mm, in
# batches (benchmarks.fea_sweep).
#   snakemake --cores 2 fea_sweep


localrules:
    fea_sweep,


rule fea_sweep:
    input:
        study_files("fea_sweep"),


rule fea_sweep_batch:
    output:
        table=f"{RESULTS}/benchmarks/fea_sweep/batch_{{batch}}.csv",
    log:
        f"{RESULTS}/logs/studies/fea_sweep_batch_{{batch}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/fea_sweep_batch_{{batch}}.tsv"
    wildcard_constraints:
        batch=r"\d+",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=60,
    params:
        fea=section("fea"),
        mesh=section("mesh"),
        finger=section("finger"),
        materials=study_materials(),
        placement=section("placement"),
        sweep=section("benchmarks", keys=("fea_sweep",)),
    script:
        "fea_sweep.py"


rule fea_sweep_summary:
    input:
        tables=expand(
            f"{RESULTS}/benchmarks/fea_sweep/batch_{{batch}}.csv",
            batch=range(config["benchmarks"]["fea_sweep"]["batches"]),
        ),
    output:
        summary=f"{RESULTS}/benchmarks/fea_sweep/summary.md",
        table=f"{RESULTS}/benchmarks/fea_sweep/scenes.csv",
    log:
        f"{RESULTS}/logs/fea/sweep_summary.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=500,
        runtime=2,
    params:
        force_cap_N=config["fea"]["force_cap_N"],
    script:
        "fea_sweep_summary.py"
