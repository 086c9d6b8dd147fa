# Render stage: camera images and log-stress maps of every FEA frame.


rule render_scene:
    input:
        result=f"{FEA}/{{object}}/{{material}}/h{{height}}/result.npz",
    output:
        index=f"{RENDER}/{{object}}/{{material}}/h{{height}}/p{{pitch}}/index.json",
    params:
        render=config["render"],
        scene=render_scene_params,
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
    log:
        f"{RESULTS}/logs/render/benchmark.log",
    threads: 1
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/render_benchmark.py"
