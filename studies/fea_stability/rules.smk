# The FEA stability study (studies/fea_stability/README.md): the hard scenes (a soft
# object, coarse and fine meshes) solved to the end or stopped with a message naming the
# scene and the step; reads benchmarks.fea_* (FEA_STUDY_KEYS).
#   snakemake --cores 2 fea_stability


rule fea_stability:
    output:
        table=f"{RESULTS}/benchmarks/fea_stability.csv",
        summary=f"{RESULTS}/benchmarks/fea_stability.md",
    log:
        f"{RESULTS}/logs/studies/fea_stability.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/fea_stability.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1200,
        runtime=6,
    params:
        fea=section("fea"),
        mesh=section("mesh"),
        finger=section("finger"),
        materials=study_materials("neoprene"),  # a case of the suite
        placement=section("placement"),
        sizes=section("benchmarks", keys=FEA_STUDY_KEYS),
    script:
        "fea_stability.py"
