# Training: one job per model of train.models (e.g. without and with occlusion), and with
# generated training objects the paper-objects model of the diversity comparison
# (<generated.compare_model>_paper_objects, see common.smk).


rule train_model:
    input:
        shards=train_shards,
        init=model_init,  # the weights it starts from (train.models.<model>.start_from)
    output:
        model=f"{TRAIN}/{{model}}/model.pt",
        torchscript=f"{TRAIN}/{{model}}/model.ts",
        settings=f"{TRAIN}/{{model}}/model.ts.json",  # what predict and calibrate read beside it
        onnx=f"{TRAIN}/{{model}}/model.onnx",
        onnx_force=f"{TRAIN}/{{model}}/model.force.onnx",
        history=f"{TRAIN}/{{model}}/history.json",
        curves=report(
            f"{TRAIN}/{{model}}/curves.png",
            caption="../report/train_curves.rst",
            category="Training",
        ),
    log:
        f"{RESULTS}/logs/train/{{model}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/train/{{model}}.tsv"
    # the longest jobs start first: training, and what it waits for (geometry, FEA and
    # render at priority 20), before the studies, the lab and the evaluations
    priority: 30
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2600,
        runtime=40,
    params:
        train=model_train_params,  # device too: the rounding follows it
        augment=model_augment,
        dataset=section(
            "dataset",
            keys=SEGMENT_KEYS + ("crop_x_mm", "crop_y_mm", "occlusion_levels", "base_band"),
        ),
        render=section("render", keys=("window_y_mm",)),
        finger=section("finger", keys=("extrusion_mm", "base_width_mm")),
    script:
        "../scripts/train_model.py"
