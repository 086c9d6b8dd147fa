# Dataset stage: the manifest of all shards and the example figure. The shards
# themselves (crop, downsample, segment) are written by render_scene (render.smk),
# in the same pass as the frames they come from.


rule dataset_manifest:
    input:
        shards=shard_files(every_height=True),
    output:
        manifest=f"{DATASET}/manifest.csv",
    log:
        f"{RESULTS}/logs/dataset/manifest.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
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
    log:
        f"{RESULTS}/logs/dataset/examples.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        dataset=section(
            "dataset",
            keys=SEGMENT_KEYS
            + ("crop_x_mm", "crop_y_mm", "noise_levels", "occlusion_levels", "occluder_value"),
        ),
    script:
        "../scripts/dataset_examples.py"
