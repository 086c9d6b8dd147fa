# Helpers of the evaluation rules (evaluate.smk): each experiment's test shards, models and
# conditions; sim-to-real's model; the diversity comparison; the rig prior's FEA.
from finray.sim2real.rig_prior import variants as rig_prior_variants


def pitch_series_shards():
    obj, mat, h = pitch_scene()
    return [f"{DATASET}/shards/{obj}/{mat}/h{h}/p{pitch_label(p)}.npz" for p in series_pitches()]


def occlusion_level_order():
    """Occlusion levels from the smallest discs to the largest (the config's keys in
    whatever order they are written)."""
    levels = config["dataset"]["occlusion_levels"]
    return sorted(levels, key=lambda k: (list(levels[k]), k))


def experiment_setup(wildcards):
    """Test shards, models and conditions of an experiment (see finray.evaluate)."""
    e, d = wildcards.experiment, train_dir(wildcards)
    if e in ("shape", "material"):  # also scored through the camera path on the renders
        # every model on the held-out shapes (each one's generalisation and its spread)
        names = ("plain", "camera", "occlusion", "pitch") if e == "shape" else ("plain", "camera")
        return {
            "shards": shard_files(splits=[e], pitch=0.0),
            "models": eval_models(*names, train_dir=d),
            "group_col": "object" if e == "shape" else "material",
            "conditions": None,
            "renders": render_index_files(pitch=0.0, splits=[e]),
        }
    if e == "occlusion":
        return {
            "shards": shard_files(splits=["shape"], pitch=0.0),
            "models": eval_models("plain", "occlusion", train_dir=d),
            "group_col": "object",
            "conditions": [[lvl, {"occlusion": lvl}] for lvl in occlusion_level_order()],
            "renders": [],
        }
    if e == "viewpoint":  # perspective renders of the held-out shapes (evaluate.viewpoint)
        return {
            "shards": shard_files(splits=["shape"], pitch=0.0, paper_heights=True),
            "models": eval_models("plain", "pitch", "camera", train_dir=d),
            "group_col": "distance_mm",
            "conditions": [[f"{p:g}", {"pitch_deg": p}] for p in series_pitches()],
            "renders": viewpoint_indices(),
        }
    # the camera model too: trained on perspective views, it is scored on the same pitches
    return {
        "shards": pitch_series_shards(),
        "models": eval_models("plain", "pitch", "camera", train_dir=d),
        "group_col": None,
        "conditions": [[f"{p:g}", {"pitch_deg": p}] for p in series_pitches()],
        "renders": [],
    }


def viewpoint_indices():
    """index.json of the viewpoint experiment's renders: every held-out shape scene at the
    paper's heights (heights_mm; not the face heights: the 3D renders cost most)."""
    paper = {float(h) for h in config["heights_mm"]}
    return sorted(
        f"{RENDER}/viewpoint/{s.object}/{s.material}/h{s.height_mm:g}/index.json"
        for s in scenes(config)
        if s.split == "shape" and s.height_mm in paper
    )


def experiment_params(wildcards):
    """Models (name, in the order compared), grouping and conditions (ordered [name,
    settings] pairs) of an experiment; the shards and model files are its inputs."""
    setup = experiment_setup(wildcards)
    return canonical(
        {
            "models": list(setup["models"]),
            "group_col": setup["group_col"],
            "conditions": setup["conditions"],
            "train_heights_mm": train_heights(),
        }
    )


def train_heights():
    """Contact heights (mm) of the training scenes, sorted (what heights.csv calls seen)."""
    return sorted({s.height_mm for s in scenes(config) if s.split == "train"})


def experiment_inputs(wildcards):
    """Test shards, model files (model.ts; its model.ts.json comes with it) and, for the
    camera path, the test views' render indices."""
    setup = experiment_setup(wildcards)
    return {
        "shards": setup["shards"],
        "models": list(setup["models"].values()),
        "renders": setup["renders"],
    }


def sim2real_model(train_dir=TRAIN):
    """The network sim-to-real starts from (finray.config.sim2real_model_name)."""
    return f"{train_dir}/{sim2real_model_name(config)}/model.pt"


def sim2real_torchscript(train_dir=TRAIN):
    """Its export, whose model.ts.json holds the training's ranges (the near_base flag)."""
    return f"{train_dir}/{sim2real_model_name(config)}/model.ts"


# The diversity comparison (evaluate.smk's evaluate_diversity, DIVERSITY_DIR there)
def diversity_files():
    """The comparison's summary where the config plans it (generated training objects and
    generated.compare_model), else nothing."""
    return [f"{DIVERSITY_DIR}/summary.json"] if DIVERSITY else []


def _diversity_or_stop():
    if not DIVERSITY:
        raise ValueError(
            f"{DIVERSITY_DIR} needs generated training objects (generated.count > 0, "
            "split train) and generated.compare_model: see config/diverse.yaml"
        )
    return DIVERSITY


def diversity_inputs(wildcards):
    """Test shards of the shape and material experiments; both models and their histories."""
    paper, model = _diversity_or_stop()
    tests = {
        f"{t}_shards": experiment_setup(SimpleNamespace(experiment=t))["shards"]
        for t in DIVERSITY_TESTS
    }
    return {
        **tests,
        "models": [model_file(paper), model_file(model)],
        "histories": [f"{TRAIN}/{m}/history.json" for m in (paper, model)],
    }


def diversity_params(wildcards):
    """Grouping of each test set (as its experiment's), the models' names and the number
    of training objects of each (the paper's, and those plus the generated ones)."""
    paper, model = _diversity_or_stop()
    train = [n for n, o in config["objects"].items() if o["split"] == "train"]
    n_gen = sum(n in GENERATED_TRAIN for n in train)
    return canonical(
        {
            "tests": {
                t: experiment_setup(SimpleNamespace(experiment=t))["group_col"]
                for t in DIVERSITY_TESTS
            },
            "setup": {
                "model": model,
                "models": {"paper_objects": paper, "with_generated": model},
                "n_generated": n_gen,
                "train_objects": {
                    "paper_objects": len(train) - n_gen,
                    "with_generated": len(train),
                },
            },
        }
    )


# The rig prior's FEA (rig_prior.smk): evaluate.sim2real.rig_prior.gain
def rig_prior_dir():
    """Where the rig prior's FEA and rig_prior.json go."""
    return f"{EVALUATE}/sim2real/rig_prior"


def rig_prior_spec():
    """evaluate.sim2real.rig_prior.gain (the ranges and scenes), or None."""
    return (config["evaluate"]["sim2real"].get("rig_prior") or {}).get("gain")


def rig_prior_input():
    """The rig prior a sim-to-real job reads: rig_prior.json where the FEA makes it."""
    return [f"{rig_prior_dir()}/rig_prior.json"] if rig_prior_spec() else []


#: what the no-context fit alone reads of evaluate.sim2real
NO_CONTEXT_ONLY = ("sim_every", "sim_folds", "sim_views")
#: what the no-context fit reads of evaluate.sim2real (the rest is the context fits')
NO_CONTEXT_KEYS = ("heads", "priors", "sampler", "level") + NO_CONTEXT_ONLY


def sim2real_params():
    """evaluate.sim2real as the context fits read it: without the no-context fit's own
    keys (NO_CONTEXT_ONLY) and what only the rig prior's FEA reads (rig_prior.gain)."""
    s = copy.deepcopy(config["evaluate"]["sim2real"])
    (s.get("rig_prior") or {}).pop("gain", None)
    return canonical({k: v for k, v in s.items() if k not in NO_CONTEXT_ONLY})


def no_context_params():
    """evaluate.sim2real as the no-context fit reads it (NO_CONTEXT_KEYS)."""
    s = config["evaluate"]["sim2real"]
    return canonical({k: s[k] for k in NO_CONTEXT_KEYS if k in s})


def rig_prior_variant(variant):
    """A variant's as-built changes (finray.sim2real.rig_prior.variants), one line if unknown."""
    v = rig_prior_variants(rig_prior_spec()).get(variant)
    if v is None:
        raise ValueError(f"no rig-prior variant {variant!r}")
    return v


def rig_prior_scenes():
    """(variant, object, height) of every FEA run of the rig prior."""
    spec = rig_prior_spec()
    return [(v, o, f"{float(h):g}") for v in rig_prior_variants(spec) for o, h in spec["scenes"]]


def rig_prior_geometry(wildcards):
    """Thicker walls: the variant's own finger and object; more friction: the training's."""
    if "thickness_delta_mm" in rig_prior_variant(wildcards.variant):
        base = f"{rig_prior_dir()}/{wildcards.variant}/geometry"
    else:
        base = GEOMETRY
    return {
        "finger": f"{base}/finger.npz",
        "object": f"{base}/objects/{wildcards.object}_h{wildcards.height}.npz",
    }


def face_figure_runs():
    """Label -> the shape experiment's heights.csv of each training the face figure
    (paper.smk) draws: the run's, and each spread variant's where the manuscript quotes
    the spread study."""
    runs = {"this run": f"{EVALUATE}/shape/heights.csv"}
    if config["evaluate"]["spread"]["manuscript"]:
        runs.update({v: f"{SPREAD}/{v}/shape/heights.csv" for v in spread_variants()})
    return runs
