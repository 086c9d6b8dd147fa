# FEA stage: one job per scene (finger x object x material x contact height).


rule fea_scene:
    input:
        finger=f"{GEOMETRY}/finger.npz",
        object=f"{GEOMETRY}/objects/{{object}}_h{{height}}.npz",
    output:
        result=f"{FEA}/{{object}}/{{material}}/h{{height}}/result.npz",
        forces=f"{FEA}/{{object}}/{{material}}/h{{height}}/forces.csv",
        summary=f"{FEA}/{{object}}/{{material}}/h{{height}}/summary.json",
    log:
        f"{RESULTS}/logs/fea/{{object}}_{{material}}_h{{height}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/fea/{{object}}_{{material}}_h{{height}}.tsv"
    priority: 20
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=600,
        runtime=1,
    params:
        fea=section("fea"),
        material=material_params,
        finger=finger_fea_params(),
        finger_material=material_constants(config["finger"]["material"]),
        split=object_split,
        # not an output: Snakemake deletes a failed job's outputs, this report stays
        failure_report=f"{FEA}/failed/{{object}}_{{material}}_h{{height}}.json",
    script:
        "../scripts/fea_scene.py"


rule fea_figures:
    input:
        summaries=fea_files("summary.json"),
        results=fea_files("result.npz"),
    output:
        curves=report(
            f"{FEA}/force_displacement.pdf",
            caption="../report/fea_curves.rst",
            category="FEA",
        ),
        curves_png=f"{FEA}/force_displacement.png",
        jamming=report(f"{FEA}/jamming.png", caption="../report/fea_jamming.rst", category="FEA"),
        table=f"{RESULTS}/benchmarks/fea_scenes.csv",
    log:
        f"{RESULTS}/logs/fea/figures.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    script:
        "../scripts/fea_figures.py"
