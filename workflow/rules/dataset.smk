# Dataset stage: crop, downsample, segment; one shard per rendered scene and a manifest.


rule dataset_shard:
    input:
        index=f"{RENDER}/{{object}}/{{material}}/h{{height}}/p{{pitch}}/index.json",
    output:
        shard=f"{DATASET}/shards/{{object}}/{{material}}/h{{height}}/p{{pitch}}.npz",
    params:
        dataset=config["dataset"],
        scene=shard_scene_params,
    log:
        f"{RESULTS}/logs/dataset/{{object}}_{{material}}_h{{height}}_p{{pitch}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/dataset/{{object}}_{{material}}_h{{height}}_p{{pitch}}.tsv"
    threads: 1
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/dataset_shard.py"


rule dataset_manifest:
    input:
        shards=shard_files(),
    output:
        manifest=f"{DATASET}/manifest.csv",
    log:
        f"{RESULTS}/logs/dataset/manifest.log",
    threads: 1
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/dataset_manifest.py"


rule dataset_examples:
    input:
        pitch_indices=pitch_series_indices(),
    output:
        pdf=report(
            f"{DATASET}/examples.pdf",
            caption="../report/dataset_examples.rst",
            category="Dataset",
        ),
        png=f"{DATASET}/examples.png",
    params:
        dataset=config["dataset"],
    log:
        f"{RESULTS}/logs/dataset/examples.log",
    threads: 1
    conda:
        "../../envs/finray.yaml"
    script:
        "../scripts/dataset_examples.py"
