# The real-time study (studies/realtime/README.md): finray predict on live 30 FPS
# streams, the camera model (benchmarks.realtime_model) on one held-out shape's renders
# at benchmarks.realtime_pitch_deg, each frame size of benchmarks.realtime_sizes.
#   snakemake --cores 2 realtime


localrules:
    realtime,


rule realtime:
    input:
        study_files("realtime"),


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
    log:
        f"{RESULTS}/logs/studies/realtime.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/realtime.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 2
    resources:
        mem_mb=1500,
        runtime=5,
    params:
        benchmarks=section(
            "benchmarks", keys=("realtime_seconds", "realtime_sizes", "realtime_pitch_deg")
        ),
        work=lambda w, output: os.path.splitext(output.json)[0],  # streams and runs' outputs
    script:
        "realtime_benchmark.py"
