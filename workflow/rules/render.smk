# Render + dataset stage: one job per rendered view renders every FEA frame (camera
# image + log-stress maps), segments the camera image and writes the view's shard
# in the same pass; only render.files_per_scene frames are also written as PNG + EXR
# (figures, inspection) next to index.json.


rule render_scene:
    input:
        result=f"{FEA}/{{object}}/{{material}}/h{{height}}/result.npz",
    output:
        index=f"{RENDER}/{{object}}/{{material}}/h{{height}}/p{{pitch}}/index.json",
        shard=f"{DATASET}/shards/{{object}}/{{material}}/h{{height}}/p{{pitch}}.npz",
    params:
        render=render_params(),
        dataset=section("dataset", keys=SHARD_KEYS),
        extrusion_mm=config["finger"]["extrusion_mm"],
        scene=shard_scene_params,
    log:
        f"{RESULTS}/logs/render/{{object}}_{{material}}_h{{height}}_p{{pitch}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/render/{{object}}_{{material}}_h{{height}}_p{{pitch}}.tsv"
    threads: 1
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/render_scene.py"


rule render_benchmark:
    input:
        result=render_benchmark_input,
    output:
        json=f"{RESULTS}/benchmarks/render_throughput.json",
    params:
        render=render_params(),
        dataset=section("dataset", keys=SHARD_KEYS),
        extrusion_mm=config["finger"]["extrusion_mm"],
    log:
        f"{RESULTS}/logs/render/benchmark.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/render_throughput.tsv"
    threads: 1
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/render_benchmark.py"
