# The default run's targets (rule all, in the Snakefile).


def all_targets():
    return [
        f"{GEOMETRY}/gallery.pdf",
        f"{GEOMETRY}/finger_surface.ply",
        f"{FEA}/force_displacement.pdf",
        f"{RESULTS}/benchmarks/fea_scenes.csv",
        f"{RESULTS}/benchmarks/fea_pareto.png",
        f"{RESULTS}/benchmarks/fea_stability.csv",
        f"{RESULTS}/benchmarks/render_throughput.json",
        f"{DATASET}/manifest.csv",
        f"{DATASET}/examples.pdf",
        f"{RESULTS}/summary.json",
        "paper/manuscript.html",
        f"{RESULTS}/benchmarks/train_pareto.csv",
        f"{RESULTS}/benchmarks/train_pareto.png",
        f"{RESULTS}/benchmarks/train_pareto.md",
        f"{RESULTS}/benchmarks/inference_latency.json",
        f"{RESULTS}/benchmarks/train_time.csv",
        f"{RESULTS}/lab/qa.json",  # the emulated lab rig's takes, ingested and checked
        f"{RESULTS}/lab/qa.png",
    ] + ([f"{EVALUATE}/sim2real/rigs/summary.json"] if rig_names() else []) + expand(
        "paper/figures/{name}.pdf", name=FIGURES) + expand(
        f"{TRAIN}/{{model}}/model.ts", model=model_names()
    ) + object_geometry_files() + (
        [f"{RESULTS}/benchmarks/realtime.md"]
        if config["benchmarks"]["realtime_model"] in config["train"]["models"] else [])
