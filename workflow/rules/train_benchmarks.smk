# Network benchmarks: run time against error (input size x width), inference latency
# of the trained default model on rendered camera frames, training time of the full
# config. Sized by the config's benchmarks section.

TRAIN_STUDY_KEYS = ("train_sizes", "train_base_channels", "train_epochs", "train_every", "train_lr",
                    "train_budget_ms", "train_tolerance")


rule train_pareto:
    input:
        shards=shard_files(splits=["train"], pitch=0.0),
    output:
        table=f"{RESULTS}/benchmarks/train_pareto.csv",
        figure=report(
            f"{RESULTS}/benchmarks/train_pareto.png",
            caption="../report/train_pareto.rst",
            category="Training",
        ),
        summary=f"{RESULTS}/benchmarks/train_pareto.md",
    params:
        benchmarks=section("benchmarks", keys=TRAIN_STUDY_KEYS + ("latency_frames",)),
        train=section("train", keys=("input_size", "base_channels", "val_fraction", "batch_size",
                                     "seed", "bf16", "channels_last", "schedule", "warmup_frac",
                                     "bn_frames", "keep")),
    log:
        f"{RESULTS}/logs/train/benchmark_pareto.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/train_pareto.tsv"
    threads: 1
    resources:
        mem_mb=2600,
        runtime=19,
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/train_pareto.py"


rule inference_latency:
    input:
        model=f"{TRAIN}/{config['benchmarks']['latency_model']}/model.ts",
        onnx=f"{TRAIN}/{config['benchmarks']['latency_model']}/model.onnx",
        onnx_force=f"{TRAIN}/{config['benchmarks']['latency_model']}/model.force.onnx",
        renders=render_index_files(pitch=0.0),
    output:
        json=f"{RESULTS}/benchmarks/inference_latency.json",
    params:
        benchmarks=section("benchmarks", keys=("latency_frames", "latency_repeats")),
    log:
        f"{RESULTS}/logs/train/benchmark_latency.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/inference_latency.tsv"
    threads: 1
    resources:
        mem_mb=700,
        runtime=1,
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/inference_latency.py"


rule realtime_benchmark:
    # finray predict on live 30 FPS streams (finray.benchmarks.realtime): both cores, the
    # predicting process on one, the stream's server on the other; nothing else runs
    input:
        model=f"{TRAIN}/{config['benchmarks']['realtime_model']}/model.ts",
        onnx=f"{TRAIN}/{config['benchmarks']['realtime_model']}/model.onnx",
        onnx_force=f"{TRAIN}/{config['benchmarks']['realtime_model']}/model.force.onnx",
        renders=viewpoint_indices()[:1],
    output:
        json=f"{RESULTS}/benchmarks/realtime.json",
        table=f"{RESULTS}/benchmarks/realtime.md",
    params:
        benchmarks=section("benchmarks", keys=("realtime_seconds", "realtime_sizes", "realtime_pitch_deg")),
        work=lambda w, output: os.path.splitext(output.json)[0],  # streams and runs' outputs
    log:
        f"{RESULTS}/logs/train/benchmark_realtime.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/realtime.tsv"
    threads: 2
    resources:
        mem_mb=1500,
        runtime=5,
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/realtime_benchmark.py"


rule train_time:
    input:
        histories=expand(f"{TRAIN}/{{model}}/history.json", model=model_names()),
        benchmarks=expand(f"{RESULTS}/benchmarks/train/{{model}}.tsv", model=model_names()),
    output:
        table=f"{RESULTS}/benchmarks/train_time.csv",
    params:
        models=model_names(),
    log:
        f"{RESULTS}/logs/train/benchmark_train_time.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/train_time.py"
