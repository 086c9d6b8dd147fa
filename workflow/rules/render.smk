# Render + dataset stage: one job per rendered view renders every FEA frame (camera
# image + log-stress maps), segments the camera image and writes the view's shard
# in the same pass; only render.files_per_scene frames are also written as PNG + EXR
# (figures, inspection) next to index.json. A training scene's front view also gets
# every frame seen by its randomised perspective camera (render.camera_views).


rule render_scene:
    input:
        result=f"{FEA}/{{object}}/{{material}}/h{{height}}/result.npz",
    output:
        index=f"{RENDER}/{{object}}/{{material}}/h{{height}}/p{{pitch}}/index.json",
        shard=f"{DATASET}/shards/{{object}}/{{material}}/h{{height}}/p{{pitch}}.npz",
    log:
        f"{RESULTS}/logs/render/{{object}}_{{material}}_h{{height}}_p{{pitch}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/render/{{object}}_{{material}}_h{{height}}_p{{pitch}}.tsv"
    priority: 20
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=800,
        runtime=1,
    params:
        render=render_params(),
        dataset=section("dataset", keys=SHARD_KEYS),
        extrusion_mm=config["finger"]["extrusion_mm"],
        scene=shard_scene_params,
        camera_views=scene_camera_views,
        base_width_mm=config["finger"]["base_width_mm"],
    script:
        "../scripts/render_scene.py"


rule viewpoint_render:
    # The viewpoint experiment's test frames: pyvista perspective renders of a held-out
    # scene at every pitch and distance (independent of the training views' raster).
    input:
        result=f"{FEA}/{{object}}/{{material}}/h{{height}}/result.npz",
    output:
        index=f"{RENDER}/viewpoint/{{object}}/{{material}}/h{{height}}/index.json",
    log:
        f"{RESULTS}/logs/render/viewpoint_{{object}}_{{material}}_h{{height}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/render/viewpoint_{{object}}_{{material}}_h{{height}}.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=1,
    params:
        render=render_params(),
        view=section("evaluate")["viewpoint"],
        pitches=series_pitches(),
        extrusion_mm=config["finger"]["extrusion_mm"],
        scene=render_scene_params,
    script:
        "../scripts/viewpoint_render.py"
