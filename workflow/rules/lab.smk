# The emulated lab rig (config `lab:`): an as-built finger's FEA, takes in the recording
# format (results/lab/<take>/), `finray ingest` of each take, and the QA against the
# emulator's truth. Only these rules and the summary (which says how the takes were
# made) read `lab:`; ingest reads the take only.


rule lab_finger:
    output:
        npz=f"{LAB}/geometry/finger.npz",
        vtu=f"{LAB}/geometry/finger.vtu",
        summary=f"{LAB}/geometry/finger.json",
        surface=f"{LAB}/geometry/finger_surface.ply",
        surface_npz=f"{LAB}/geometry/finger_surface.npz",
    log:
        f"{RESULTS}/logs/lab/finger.log",
    benchmark:
        f"{RESULTS}/benchmarks/lab/finger.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=200,
        runtime=1,
    params:
        finger=lab_finger(),
        mesh=section("mesh"),
    script:
        "../scripts/geometry_finger.py"


rule lab_object:
    input:
        finger=f"{LAB}/geometry/finger.json",
        polygon=lab_polygon_input,
    output:
        npz=f"{LAB}/geometry/objects/{{object}}_h{{height}}.npz",
        vtu=f"{LAB}/geometry/objects/{{object}}_h{{height}}.vtu",
    log:
        f"{RESULTS}/logs/lab/{{object}}_h{{height}}_object.log",
    benchmark:
        f"{RESULTS}/benchmarks/lab/{{object}}_h{{height}}_object.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=100,
        runtime=1,
    params:
        spec=lab_object_spec,
        deformable=False,  # printed PLA: rigid against the finger
        finger=lab_finger(),
        mesh=section("mesh", keys=("size_mm", "min_angle_deg")),
        placement=canonical({"gap_mm": config["lab"]["motion"]["gap_mm"]}),
    script:
        "../scripts/geometry_object.py"


rule lab_fea:
    input:
        finger=f"{LAB}/geometry/finger.npz",
        object=f"{LAB}/geometry/objects/{{object}}_h{{height}}.npz",
    output:
        result=f"{LAB}/fea/{{object}}_h{{height}}/result.npz",
        forces=f"{LAB}/fea/{{object}}_h{{height}}/forces.csv",
        summary=f"{LAB}/fea/{{object}}_h{{height}}/summary.json",
    log:
        f"{RESULTS}/logs/lab/{{object}}_h{{height}}_fea.log",
    benchmark:
        f"{RESULTS}/benchmarks/lab/{{object}}_h{{height}}_fea.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=500,
        runtime=1,
    params:
        fea=canonical(
            as_built_fea(config["fea"], config["lab"]["as_built"], config["lab"]["motion"])
        ),
        finger=finger_fea_params(),
        finger_material=canonical(
            as_built_material(
                config["materials"][config["finger"]["material"]], config["lab"]["as_built"]
            )
        ),
        failure_report=f"{LAB}/fea/failed/{{object}}_h{{height}}.json",
    script:
        "../scripts/lab_fea.py"


rule lab_take:
    input:
        result=f"{LAB}/fea/{{object}}_h{{height}}/result.npz",
    output:
        video=f"{LAB}/{{object}}_h{{height}}/take.mp4",
        forces=f"{LAB}/{{object}}_h{{height}}/forces.csv",
        take=f"{LAB}/{{object}}_h{{height}}/take.json",
        masks=f"{LAB}/{{object}}_h{{height}}/truth/masks.npz",
        frames=f"{LAB}/{{object}}_h{{height}}/truth/frames.csv",
        truth=f"{LAB}/{{object}}_h{{height}}/truth/truth.json",
    log:
        f"{RESULTS}/logs/lab/{{object}}_h{{height}}_take.log",
    benchmark:
        f"{RESULTS}/benchmarks/lab/{{object}}_h{{height}}_take.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1100,
        runtime=1,
    params:
        lab=section("lab", keys=("motion", "camera", "look", "sensor")),
        # the print's time dependence (as_built's other keys act through the FEA)
        print_law=canonical(as_built_print_law(config["lab"]["as_built"])),
        seed=lab_take_seed,
        extrusion_mm=config["finger"]["extrusion_mm"],
    script:
        "../scripts/lab_take.py"


rule lab_ingest:
    input:
        video=f"{LAB}/{{object}}_h{{height}}/take.mp4",
        forces=f"{LAB}/{{object}}_h{{height}}/forces.csv",
        take=f"{LAB}/{{object}}_h{{height}}/take.json",
    output:
        shard=f"{LAB}/ingest/{{object}}_h{{height}}/shard.npz",
        frames=f"{LAB}/ingest/{{object}}_h{{height}}/frames.csv",
        sync=f"{LAB}/ingest/{{object}}_h{{height}}/sync.json",
        summary=f"{LAB}/ingest/{{object}}_h{{height}}/ingest.json",
        qa=f"{LAB}/ingest/{{object}}_h{{height}}/qa.png",
        masks=f"{LAB}/ingest/{{object}}_h{{height}}/masks.npz",
    log:
        f"{RESULTS}/logs/lab/{{object}}_h{{height}}_ingest.log",
    benchmark:
        f"{RESULTS}/benchmarks/lab/{{object}}_h{{height}}_ingest.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=900,
        runtime=1,
    params:
        # what a real rig's take would be ingested with: the dataset's crop and the
        # nominal finger, never lab:
        dataset=section("dataset", keys=("sizes", "crop_x_mm", "crop_y_mm", "base_band")),
        base_width_mm=config["finger"]["base_width_mm"],
    script:
        "../scripts/lab_ingest.py"


rule lab_qa:
    input:
        takes=[f"{LAB}/{t}/truth/truth.json" for t in lab_takes()],
        masks=[f"{LAB}/{t}/truth/masks.npz" for t in lab_takes()],
        truth_frames=[f"{LAB}/{t}/truth/frames.csv" for t in lab_takes()],
        ingested=[f"{LAB}/ingest/{t}/ingest.json" for t in lab_takes()],
        shards=[f"{LAB}/ingest/{t}/shard.npz" for t in lab_takes()],
        ingest_masks=[f"{LAB}/ingest/{t}/masks.npz" for t in lab_takes()],
        model=f"{TRAIN}/plain/model.ts",
        # also scored on the takes, where configured: the camera model
        others=list(eval_models("camera").values()),
    output:
        takes=f"{LAB}/qa.csv",
        frames=f"{LAB}/qa_frames.csv",
        summary=f"{LAB}/qa.json",
        figure=f"{LAB}/qa.png",
    log:
        f"{RESULTS}/logs/lab/qa.log",
    benchmark:
        f"{RESULTS}/benchmarks/lab/qa.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1400,
        runtime=2,
    params:
        size=config["train"]["input_size"],
        others=list(eval_models("camera")),
    script:
        "../scripts/lab_qa.py"
