# The rig prior's gain from the FEA (evaluate.sim2real.rig_prior.gain; finray.evaluate.
# rig_prior): training scenes simulated again with thicker walls (their own geometry) and
# with more friction (the training geometry), each variant's force against the training
# scene's. Never reads lab:.

RIG_PRIOR = rig_prior_dir()


wildcard_constraints:
    variant=r"(t|mu)[0-9.]+",


use rule lab_finger as rig_prior_finger with:
    output:
        npz=f"{RIG_PRIOR}/{{variant}}/geometry/finger.npz",
        vtu=f"{RIG_PRIOR}/{{variant}}/geometry/finger.vtu",
        summary=f"{RIG_PRIOR}/{{variant}}/geometry/finger.json",
        surface=f"{RIG_PRIOR}/{{variant}}/geometry/finger_surface.ply",
        surface_npz=f"{RIG_PRIOR}/{{variant}}/geometry/finger_surface.npz",
    log:
        f"{RESULTS}/logs/evaluate/rig_prior/{{variant}}_finger.log",
    benchmark:
        f"{RESULTS}/benchmarks/evaluate/rig_prior/{{variant}}_finger.tsv"
    params:
        finger=lambda w: canonical(as_built_finger(config["finger"], rig_prior_variant(w.variant))),
        mesh=section("mesh"),


use rule lab_object as rig_prior_object with:
    input:
        finger=f"{RIG_PRIOR}/{{variant}}/geometry/finger.json",
        polygon=polygon_file_input,
    output:
        npz=f"{RIG_PRIOR}/{{variant}}/geometry/objects/{{object}}_h{{height}}.npz",
        vtu=f"{RIG_PRIOR}/{{variant}}/geometry/objects/{{object}}_h{{height}}.vtu",
    log:
        f"{RESULTS}/logs/evaluate/rig_prior/{{variant}}_{{object}}_h{{height}}_object.log",
    benchmark:
        f"{RESULTS}/benchmarks/evaluate/rig_prior/{{variant}}_{{object}}_h{{height}}_object.tsv"
    params:
        spec=object_spec,
        deformable=False,  # the training scenes' steel
        finger=lambda w: canonical(as_built_finger(config["finger"], rig_prior_variant(w.variant))),
        mesh=section("mesh", keys=("size_mm", "min_angle_deg")),
        placement=section("placement"),


rule rig_prior_fea:
    input:
        unpack(rig_prior_geometry),
    output:
        result=f"{RIG_PRIOR}/{{variant}}/fea/{{object}}_h{{height}}/result.npz",
        forces=f"{RIG_PRIOR}/{{variant}}/fea/{{object}}_h{{height}}/forces.csv",
        summary=f"{RIG_PRIOR}/{{variant}}/fea/{{object}}_h{{height}}/summary.json",
    log:
        f"{RESULTS}/logs/evaluate/rig_prior/{{variant}}_{{object}}_h{{height}}_fea.log",
    benchmark:
        f"{RESULTS}/benchmarks/evaluate/rig_prior/{{variant}}_{{object}}_h{{height}}_fea.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=600,
        runtime=1,
    params:
        fea=lambda w: canonical(
            config["fea"]
            | {k: v for k, v in rig_prior_variant(w.variant).items() if k == "friction"}
        ),
        finger=finger_fea_params(),
        finger_material=material_constants(config["finger"]["material"]),
        failure_report=lambda w: f"{RIG_PRIOR}/{w.variant}/fea/failed/{w.object}_h{w.height}.json",
    script:
        "../scripts/rig_prior_fea.py"


rule rig_prior:
    input:
        nominal=lambda w: [f"{FEA}/{o}/steel/h{h}/forces.csv" for _, o, h in rig_prior_scenes()],
        variants=lambda w: [
            f"{RIG_PRIOR}/{v}/fea/{o}_h{h}/forces.csv" for v, o, h in rig_prior_scenes()
        ],
    output:
        json=f"{RIG_PRIOR}/rig_prior.json",
    log:
        f"{RESULTS}/logs/evaluate/rig_prior/rig_prior.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=300,
        runtime=1,
    params:
        spec=lambda w: canonical(rig_prior_spec()),
        nominal_friction=config["fea"]["friction"],
        runs=lambda w: [list(r) for r in rig_prior_scenes()],
    script:
        "../scripts/rig_prior.py"
