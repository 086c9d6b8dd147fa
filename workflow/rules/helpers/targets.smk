# The default run's targets (the inputs of `all` in workflow/Snakefile), the product
# only; the studies' targets are in helpers/studies.smk.


def all_targets():
    return (
        [
            f"{GEOMETRY}/gallery.pdf",
            f"{GEOMETRY}/finger_surface.ply",
            f"{FEA}/force_displacement.pdf",
            f"{RESULTS}/benchmarks/fea_scenes.csv",
            f"{DATASET}/manifest.csv",
            f"{DATASET}/examples.pdf",
            f"{RESULTS}/summary.json",
            "paper/manuscript.html",
            f"{RESULTS}/benchmarks/inference_latency.json",
            f"{RESULTS}/benchmarks/train_time.csv",
            f"{RESULTS}/lab/qa.json",  # the emulated lab rig's takes, ingested and checked
            f"{RESULTS}/lab/qa.png",
        ]
        + ([f"{EVALUATE}/sim2real/rigs/summary.json"] if rig_names() else [])
        + expand("paper/figures/{name}.pdf", name=FIGURES)
        + expand(f"{TRAIN}/{{model}}/model.ts", model=model_names())
        + object_geometry_files()
    )
