# The studies (studies/<name>/: rules.smk, code, README.md of what each found): what each
# builds, its own target, and what the product reads of them where they exist. No study
# is in `rule all`; `snakemake --cores 2 studies` builds them all, `snakemake --cores 2
# <name>` one (functions and constants only: the Snakefile includes the rule files).

#: the config keys the FEA studies read (benchmarks.fea_*)
FEA_STUDY_KEYS = (
    "fea_reference_mesh_mm",
    "fea_mesh_sizes_mm",
    "fea_p1_mesh_sizes_mm",
    "fea_arc_chord_sizes_mm",
    "fea_fine_mesh_mm",
    "fea_coarse_mesh_mm",
)
#: the config keys the network-size study reads (benchmarks.train_*)
TRAIN_STUDY_KEYS = (
    "train_sizes",
    "train_base_channels",
    "train_epochs",
    "train_every",
    "train_lr",
    "train_budget_ms",
    "train_tolerance",
)


def study_registry():
    """name -> {"title", "files" (what its target builds), "figure" (the one the
    manuscript shows, or None)}, in the order the manuscript lists them. The real-time
    study only where its model (benchmarks.realtime_model) is trained."""
    bench = f"{RESULTS}/benchmarks"
    reg = {
        "fea_cost": {
            "title": "FEA cost against accuracy (mesh and element order)",
            "files": [f"{bench}/fea_pareto.{e}" for e in ("csv", "png", "md")],
            "figure": f"{bench}/fea_pareto.png",
        },
        "fea_stability": {
            "title": "FEA stability on the hard scenes",
            "files": [f"{bench}/fea_stability.{e}" for e in ("csv", "md")],
            "figure": None,
        },
        "fea_sweep": {
            "title": "FEA sweep over the whole face",
            "files": [f"{bench}/fea_sweep/summary.md", f"{bench}/fea_sweep/scenes.csv"],
            "figure": None,
        },
        "render_throughput": {
            "title": "Render throughput (2D rasteriser and 3D renderer)",
            "files": [f"{bench}/render_throughput.json"],
            "figure": None,
        },
        "network_size": {
            "title": "Network size: run time against error",
            "files": [f"{bench}/train_pareto.{e}" for e in ("csv", "png", "md")],
            "figure": f"{bench}/train_pareto.png",
        },
        "realtime": {
            "title": "Real time: finray predict on live 30 FPS streams",
            "files": [f"{bench}/realtime.json", f"{bench}/realtime.md"],
            "figure": None,
        },
        "seeds": {
            "title": "Seeds and numeric types: one training is one draw",
            "files": [f"{SPREAD}/summary.json", f"{SPREAD}/spread.md", f"{SPREAD}/spread.png"]
            + ([f"{SPREAD}/rigs/summary.json", f"{SPREAD}/rigs/rigs.png"] if rig_names() else []),
            "figure": f"{SPREAD}/spread.png",
        },
        "print_time": {
            "title": "A viscoelastic print: the time-dependent calibration against the static one",
            "files": [
                f"{EVALUATE}/print_time/{f}" for f in ("summary.json", "phases.md", "phases.png")
            ],
            "figure": f"{EVALUATE}/print_time/phases.png",
        },
        "training_budget": {
            "title": "Training budget: CPU time against error",
            "files": [f"{bench}/training_budget.{e}" for e in ("json", "md", "csv", "png")],
            "figure": f"{bench}/training_budget.png",
        },
    }
    if config["benchmarks"]["realtime_model"] not in config["train"]["models"]:
        del reg["realtime"]
    return reg


def study_files(name):
    """What the study ``name``'s own target builds."""
    return study_registry()[name]["files"]


def study_targets():
    """Every study's files: the target ``studies``."""
    return [f for s in study_registry().values() for f in s["files"]]


def built(paths):
    """Those of ``paths`` that exist now (a study's output where it was built): an input
    that never makes the product build a study, and reruns its reader once it is built
    (a new input file). Read when the DAG is built: a study built in the same invocation
    reaches its reader on the next one."""
    return [p for p in paths if os.path.exists(p)]


def manuscript_studies():
    """What the manuscript says of each study: whether it was built (every file of its
    target exists), its figure relative to paper/ where it was, its first result file,
    and the command that builds it (the manuscript's optional inputs are ``built(...)``
    of the same files)."""
    out = []
    for name, s in study_registry().items():
        done = all(os.path.exists(f) for f in s["files"])
        out.append(
            {
                "name": name,
                "title": s["title"],
                "readme": f"studies/{name}/README.md",
                "built": done,
                "result": s["files"][0],
                "figure": os.path.relpath(s["figure"], PAPER) if done and s["figure"] else None,
                "command": f"snakemake --cores 2 {name}",
            }
        )
    return out


# The print-time study (studies/print_time/rules.smk)
def print_time_variants():
    """The run's own models ("run") and the seeds study's other variants."""
    own = spread_variant(config["train"]["seed"], config["train"]["bf16"])
    return ["run"] + [v for v in spread_variants() if v != own]


def print_time_dir(variant):
    """Where a variant's time-dependent sim-to-real lies (the product's, or the seeds study's)."""
    return f"{EVALUATE}/sim2real" if variant == "run" else f"{SPREAD}/{variant}/sim2real"


def print_time_train(w):
    return TRAIN if w.variant == "run" else f"{SPREAD}/{w.variant}/train"


def static_sim2real_params():
    """evaluate.sim2real as the context fits read it, the print's law fixed at none."""
    s = copy.deepcopy(sim2real_params())
    s["priors"] = {**s.get("priors", {}), "relax": [0.0, 0.0], "softening": [0.0, 0.0]}
    return canonical(s)
