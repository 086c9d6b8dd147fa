# Geometry stage: finger mesh and extruded surface, objects placed at each contact height.


rule geometry_finger:
    output:
        npz=f"{GEOMETRY}/finger.npz",
        vtu=f"{GEOMETRY}/finger.vtu",
        summary=f"{GEOMETRY}/finger.json",
        surface=f"{GEOMETRY}/finger_surface.ply",
        surface_npz=f"{GEOMETRY}/finger_surface.npz",
    log:
        f"{RESULTS}/logs/geometry/finger.log",
    benchmark:
        f"{RESULTS}/benchmarks/geometry/finger.tsv"
    priority: 20
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=200,
        runtime=1,
    params:
        finger=section("finger"),
        mesh=section("mesh"),
    script:
        "../scripts/geometry_finger.py"


rule geometry_object:
    input:
        finger=f"{GEOMETRY}/finger.json",
        polygon=polygon_file_input,
    output:
        npz=f"{GEOMETRY}/objects/{{object}}_h{{height}}.npz",
        vtu=f"{GEOMETRY}/objects/{{object}}_h{{height}}.vtu",
    log:
        f"{RESULTS}/logs/geometry/{{object}}_h{{height}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/geometry/{{object}}_h{{height}}.tsv"
    priority: 20
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=100,
        runtime=1,
    params:
        spec=object_spec,
        deformable=object_deformable,
        finger=section("finger"),
        mesh=section("mesh", keys=("size_mm", "min_angle_deg")),
        placement=section("placement"),
    script:
        "../scripts/geometry_object.py"


rule geometry_gallery:
    input:
        finger=f"{GEOMETRY}/finger.npz",
        objects=object_geometry_files(),
    output:
        pdf=report(
            f"{GEOMETRY}/gallery.pdf",
            caption="../report/geometry_gallery.rst",
            category="Geometry",
        ),
        png=f"{GEOMETRY}/gallery.png",
    log:
        f"{RESULTS}/logs/geometry/gallery.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        splits=object_splits(),
    script:
        "../scripts/geometry_gallery.py"
