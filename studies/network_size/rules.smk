# The network-size study (studies/network_size/README.md): run time against error over
# input sizes and widths (benchmarks.train_*: TRAIN_STUDY_KEYS), each variant trained a
# few epochs on a subset of the training frames; a Pareto front.
#   snakemake --cores 2 network_size


localrules:
    network_size,


rule network_size:
    input:
        study_files("network_size"),


rule train_pareto:
    input:
        shards=shard_files(splits=["train"], pitch=0.0),
    output:
        table=f"{RESULTS}/benchmarks/train_pareto.csv",
        figure=report(
            f"{RESULTS}/benchmarks/train_pareto.png",
            caption="caption.rst",
            category="Training",
        ),
        summary=f"{RESULTS}/benchmarks/train_pareto.md",
    log:
        f"{RESULTS}/logs/studies/train_pareto.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/train_pareto.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2600,
        runtime=19,
    params:
        benchmarks=section("benchmarks", keys=TRAIN_STUDY_KEYS + ("latency_frames",)),
        train=section(
            "train",
            keys=(
                "input_size",
                "base_channels",
                "val_fraction",
                "batch_size",
                "seed",
                "bf16",
                "channels_last",
                "schedule",
                "warmup_frac",
                "bn_frames",
                "keep",
                "ema_decay",
            ),
        ),
    script:
        "train_pareto.py"
