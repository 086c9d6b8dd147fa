# The FEA cost study (studies/fea_cost/README.md): run time against accuracy of the
# finger's mesh and element order (a Pareto front), on the config's own scenes. Pure
# compute from the config (no input files): the params carry the config sections it
# reads (benchmarks.fea_*: FEA_STUDY_KEYS), so that editing them re-runs the study and nothing else.
#   snakemake --cores 2 fea_cost


localrules:
    fea_cost,


rule fea_cost:
    input:
        study_files("fea_cost"),


rule fea_pareto:
    output:
        table=f"{RESULTS}/benchmarks/fea_pareto.csv",
        figure=report(
            f"{RESULTS}/benchmarks/fea_pareto.png",
            caption="caption.rst",
            category="FEA",
        ),
        summary=f"{RESULTS}/benchmarks/fea_pareto.md",
    log:
        f"{RESULTS}/logs/studies/fea_pareto.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/fea_pareto.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1400,
        runtime=12,
    params:
        fea=section("fea"),
        mesh=section("mesh"),
        finger=section("finger"),
        materials=study_materials(),
        placement=section("placement"),
        sizes=section("benchmarks", keys=FEA_STUDY_KEYS),
    script:
        "fea_pareto.py"
