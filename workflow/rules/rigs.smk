# More emulated rigs (lab.rigs): rig<i>'s whole lab section drawn by finray.emulator.rigs, its
# takes made and ingested by the lab rules' scripts (results/lab/rigs/<rig>/), and
# sim-to-real run on each (results/evaluate/sim2real/rigs/<rig>/), beside the configured
# rig; sim2real_rigs gives each figure per rig and its mean and range over the rigs.

RIGS = f"{LAB}/rigs"
RIGS_EVAL = f"{EVALUATE}/sim2real/rigs"


wildcard_constraints:
    rig=r"rig\d+",


use rule lab_finger as rig_finger with:
    output:
        npz=f"{RIGS}/{{rig}}/geometry/finger.npz",
        vtu=f"{RIGS}/{{rig}}/geometry/finger.vtu",
        summary=f"{RIGS}/{{rig}}/geometry/finger.json",
        surface=f"{RIGS}/{{rig}}/geometry/finger_surface.ply",
        surface_npz=f"{RIGS}/{{rig}}/geometry/finger_surface.npz",
    log:
        f"{RESULTS}/logs/lab/rigs/{{rig}}/finger.log",
    benchmark:
        f"{RESULTS}/benchmarks/lab/rigs/{{rig}}/finger.tsv"
    params:
        finger=lambda w: lab_finger(rig_lab(w.rig)),
        mesh=section("mesh"),


use rule lab_object as rig_object with:
    input:
        finger=f"{RIGS}/{{rig}}/geometry/finger.json",
        polygon=lab_polygon_input,
    output:
        npz=f"{RIGS}/{{rig}}/geometry/objects/{{object}}_h{{height}}.npz",
        vtu=f"{RIGS}/{{rig}}/geometry/objects/{{object}}_h{{height}}.vtu",
    log:
        f"{RESULTS}/logs/lab/rigs/{{rig}}/{{object}}_h{{height}}_object.log",
    benchmark:
        f"{RESULTS}/benchmarks/lab/rigs/{{rig}}/{{object}}_h{{height}}_object.tsv"
    params:
        spec=lambda w: canonical(rig_lab(w.rig)["objects"][w.object]),
        deformable=False,
        finger=lambda w: lab_finger(rig_lab(w.rig)),
        mesh=section("mesh", keys=("size_mm", "min_angle_deg")),
        placement=lambda w: canonical({"gap_mm": rig_lab(w.rig)["motion"]["gap_mm"]}),


use rule lab_fea as rig_fea with:
    input:
        finger=f"{RIGS}/{{rig}}/geometry/finger.npz",
        object=f"{RIGS}/{{rig}}/geometry/objects/{{object}}_h{{height}}.npz",
    output:
        result=f"{RIGS}/{{rig}}/fea/{{object}}_h{{height}}/result.npz",
        forces=f"{RIGS}/{{rig}}/fea/{{object}}_h{{height}}/forces.csv",
        summary=f"{RIGS}/{{rig}}/fea/{{object}}_h{{height}}/summary.json",
    log:
        f"{RESULTS}/logs/lab/rigs/{{rig}}/{{object}}_h{{height}}_fea.log",
    benchmark:
        f"{RESULTS}/benchmarks/lab/rigs/{{rig}}/{{object}}_h{{height}}_fea.tsv"
    params:
        fea=lambda w: canonical(
            as_built_fea(config["fea"], rig_lab(w.rig)["as_built"], rig_lab(w.rig)["motion"])
        ),
        finger=finger_fea_params(),
        finger_material=lambda w: canonical(
            as_built_material(
                config["materials"][config["finger"]["material"]], rig_lab(w.rig)["as_built"]
            )
        ),
        failure_report=lambda w: f"{RIGS}/{w.rig}/fea/failed/{w.object}_h{w.height}.json",


use rule lab_take as rig_take with:
    input:
        result=f"{RIGS}/{{rig}}/fea/{{object}}_h{{height}}/result.npz",
    output:
        video=f"{RIGS}/{{rig}}/{{object}}_h{{height}}/take.mp4",
        forces=f"{RIGS}/{{rig}}/{{object}}_h{{height}}/forces.csv",
        take=f"{RIGS}/{{rig}}/{{object}}_h{{height}}/take.json",
        masks=f"{RIGS}/{{rig}}/{{object}}_h{{height}}/truth/masks.npz",
        frames=f"{RIGS}/{{rig}}/{{object}}_h{{height}}/truth/frames.csv",
        truth=f"{RIGS}/{{rig}}/{{object}}_h{{height}}/truth/truth.json",
    log:
        f"{RESULTS}/logs/lab/rigs/{{rig}}/{{object}}_h{{height}}_take.log",
    benchmark:
        f"{RESULTS}/benchmarks/lab/rigs/{{rig}}/{{object}}_h{{height}}_take.tsv"
    params:
        lab=lambda w: canonical(
            {k: rig_lab(w.rig)[k] for k in ("motion", "camera", "look", "sensor")}
        ),
        print_law=lambda w: canonical(as_built_print_law(rig_lab(w.rig)["as_built"])),
        seed=rig_take_seed,
        extrusion_mm=config["finger"]["extrusion_mm"],


use rule lab_ingest as rig_ingest with:
    input:
        video=f"{RIGS}/{{rig}}/{{object}}_h{{height}}/take.mp4",
        forces=f"{RIGS}/{{rig}}/{{object}}_h{{height}}/forces.csv",
        take=f"{RIGS}/{{rig}}/{{object}}_h{{height}}/take.json",
    output:
        shard=f"{RIGS}/{{rig}}/ingest/{{object}}_h{{height}}/shard.npz",
        frames=f"{RIGS}/{{rig}}/ingest/{{object}}_h{{height}}/frames.csv",
        sync=f"{RIGS}/{{rig}}/ingest/{{object}}_h{{height}}/sync.json",
        summary=f"{RIGS}/{{rig}}/ingest/{{object}}_h{{height}}/ingest.json",
        qa=f"{RIGS}/{{rig}}/ingest/{{object}}_h{{height}}/qa.png",
        masks=f"{RIGS}/{{rig}}/ingest/{{object}}_h{{height}}/masks.npz",
    log:
        f"{RESULTS}/logs/lab/rigs/{{rig}}/{{object}}_h{{height}}_ingest.log",
    benchmark:
        f"{RESULTS}/benchmarks/lab/rigs/{{rig}}/{{object}}_h{{height}}_ingest.tsv"
    params:
        dataset=section("dataset", keys=("sizes", "crop_x_mm", "crop_y_mm", "base_band")),
        base_width_mm=config["finger"]["base_width_mm"],


use rule sim2real as rig_sim2real with:
    input:
        lab=lambda w: [f"{RIGS}/{w.rig}/ingest/{t}/shard.npz" for t in lab_takes(rig_lab(w.rig))],
        motion=lambda w: [f"{RIGS}/{w.rig}/{t}/truth/frames.csv" for t in lab_takes(rig_lab(w.rig))],
        model=sim2real_model(),
        torchscript=sim2real_torchscript(),
        no_context=f"{EVALUATE}/sim2real/no_context.pt",  # the simulation's: every rig's
        rig_prior=rig_prior_input(),
    output:
        metrics=f"{RIGS_EVAL}/{{rig}}/metrics.csv",
        frames=f"{RIGS_EVAL}/{{rig}}/frames.csv",
        summary=f"{RIGS_EVAL}/{{rig}}/summary.json",
        calibrations=f"{RIGS_EVAL}/{{rig}}/calibrations.json",
        corner=f"{RIGS_EVAL}/{{rig}}/corner.pdf",
    log:
        f"{RESULTS}/logs/evaluate/sim2real_{{rig}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/evaluate/sim2real_{{rig}}.tsv"


rule sim2real_rigs:
    # sim-to-real on every rig: the configured one and the drawn ones
    input:
        default=f"{EVALUATE}/sim2real/summary.json",
        rigs=expand(f"{RIGS_EVAL}/{{rig}}/summary.json", rig=rig_names()),
    output:
        json=f"{RIGS_EVAL}/summary.json",
        table=f"{RIGS_EVAL}/rigs.md",
        csv=f"{RIGS_EVAL}/rigs.csv",
        figure=report(
            f"{RIGS_EVAL}/rigs.png", caption="../report/sim2real_rigs.rst", category="Sim-to-real"
        ),
        phases=f"{RIGS_EVAL}/rigs_phases.png",
    log:
        f"{RESULTS}/logs/evaluate/sim2real_rigs.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=600,
        runtime=2,
    params:
        # how each rig was emulated (its objects: in its takes' take.json)
        rigs=lambda w: canonical(
            {
                r: {k: rig_lab(r)[k] for k in ("as_built", "camera", "heights_mm")}
                for r in rig_names()
            }
        ),
    script:
        script_path("sim2real_rigs.py")  # (also run by the seeds study's `use rule`)


rule sim2real_selection_rigs:
    # sim-to-real on the rigs settings are chosen on (lab.rigs.selection), apart from the
    # reported ones; a target of its own, not in the default run
    input:
        rigs=expand(f"{RIGS_EVAL}/{{rig}}/summary.json", rig=selection_rig_names()),
    output:
        json=f"{RIGS_EVAL}/selection/summary.json",
        table=f"{RIGS_EVAL}/selection/rigs.md",
        csv=f"{RIGS_EVAL}/selection/rigs.csv",
        figure=f"{RIGS_EVAL}/selection/rigs.png",
    log:
        f"{RESULTS}/logs/evaluate/sim2real_selection_rigs.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=600,
        runtime=2,
    params:
        rigs=lambda w: canonical(
            {
                r: {k: rig_lab(r)[k] for k in ("as_built", "camera", "heights_mm")}
                for r in selection_rig_names()
            }
        ),
    script:
        script_path("sim2real_rigs.py")  # (also run by the seeds study's `use rule`)


rule figure_sim2real_rigs:
    input:
        csv=f"{RIGS_EVAL}/rigs.csv",
        summary=f"{RIGS_EVAL}/summary.json",
    output:
        pdf=report(
            f"{PAPER}/figures/sim2real_rigs.pdf",
            caption="../report/sim2real_rigs.rst",
            category="Paper",
        ),
        png=f"{PAPER}/figures/sim2real_rigs.png",
    log:
        f"{RESULTS}/logs/paper/sim2real_rigs.log",
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=2,
    params:
        figure="sim2real_rigs",
    script:
        "../scripts/paper_figure.py"
