# The speed of the product (the paper's speed experiment, section 6 of the manuscript):
# the trained model's inference latency on rendered frames, and the trainings' time.
# (The studies' timings are in studies/; evaluate_speed, in paper.smk, gathers both.)


rule inference_latency:
    input:
        model=f"{TRAIN}/{config['benchmarks']['latency_model']}/model.ts",
        onnx=f"{TRAIN}/{config['benchmarks']['latency_model']}/model.onnx",
        onnx_force=f"{TRAIN}/{config['benchmarks']['latency_model']}/model.force.onnx",
        renders=render_index_files(pitch=0.0),
    output:
        json=f"{RESULTS}/benchmarks/inference_latency.json",
    log:
        f"{RESULTS}/logs/studies/inference_latency.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/inference_latency.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=700,
        runtime=1,
    params:
        benchmarks=section("benchmarks", keys=("latency_frames", "latency_repeats")),
    script:
        "../scripts/inference_latency.py"


rule train_time:
    input:
        histories=expand(f"{TRAIN}/{{model}}/history.json", model=model_names()),
        benchmarks=expand(f"{RESULTS}/benchmarks/train/{{model}}.tsv", model=model_names()),
    output:
        table=f"{RESULTS}/benchmarks/train_time.csv",
    log:
        f"{RESULTS}/logs/train/benchmark_train_time.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        models=model_names(),
    script:
        "../scripts/train_time.py"
