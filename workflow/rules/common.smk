# Config validation and target lists. Stage rules use these helpers only.
import os
import sys
from dataclasses import fields
from types import SimpleNamespace

import zlib

import yaml
from snakemake.utils import update_config

from finray.config import (ConfigError, diversity_models, generated_training_objects,
                           object_is_meshed, scenes, validate_config)
from finray.dataset import pitch_object, scene_splits
from finray.dataset.shards import SHARD_KEYS
from finray.lab.as_built import as_built_fea, as_built_finger, as_built_material
from finray.render import RenderParams

DEFAULT_CONFIGFILE = os.path.join(workflow.basedir, "config", "config.yaml")
if not workflow.config_settings.configfiles:
    # no --configfile: the paper's full set-up, with any --config KEY=VALUE on top
    _overrides = dict(config)
    config.clear()
    config.update(yaml.safe_load(open(DEFAULT_CONFIGFILE)))
    update_config(config, _overrides)

try:
    _validated = validate_config(config, base_dir=workflow.basedir)
    try:  # the viewpoint study needs a held-out shape (or dataset.pitch_object)
        pitch_object(_validated)
    except ValueError as _exc:
        raise ConfigError("dataset.pitch_object", str(_exc).split(": ", 1)[-1]) from None
except ConfigError as _err:
    sys.stderr.write(f"finray: config error: {_err}\n")
    sys.exit(1)
config.clear()
config.update(_validated)

RESULTS = "results"
GEOMETRY = f"{RESULTS}/geometry"
FEA = f"{RESULTS}/fea"
RENDER = f"{RESULTS}/render"
DATASET = f"{RESULTS}/dataset"
TRAIN = f"{RESULTS}/train"

# one thread per job: the DAG runs jobs side by side (numpy/scipy/torch would
# otherwise each start a thread per core and fight for the two cores)
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


# ------------------------------------------------------------------ provenance
# Every config value a job reads is a param (or input) of that job, so that changing it
# re-plans exactly the jobs that read it. Snakemake records a param by its repr: params
# are passed in canonical form (mapping keys sorted) so that the same config with its
# keys in another order re-plans nothing (tests/test_provenance.py).

SEGMENT_KEYS = ("threshold", "foreground", "min_object_frac", "max_hole_frac", "keep_largest")


def canonical(value):
    """``value`` with the keys of every mapping sorted (recursively), lists kept in order."""
    if isinstance(value, dict):
        return {k: canonical(value[k]) for k in sorted(value)}
    if isinstance(value, (list, tuple)):
        return [canonical(v) for v in value]
    return value


def section(name, keys=None, drop=()):
    """Config section ``name`` (only ``keys`` if given, without ``drop``), canonical."""
    sec = config[name]
    return canonical({k: v for k, v in sec.items()
                      if (keys is None or k in keys) and k not in drop})


def render_params():
    """The render section as the renderer reads it (``pitches_deg`` only picks the views)."""
    return section("render", keys={f.name for f in fields(RenderParams)})


def material_constants(name):
    """What the solver reads of a material (its ``source`` is documentation only)."""
    return canonical({k: v for k, v in config["materials"][name].items() if k != "source"})


wildcard_constraints:
    object="[A-Za-z0-9_-]+",
    material="[A-Za-z0-9_-]+",
    height=r"\d+(\.\d+)?",
    pitch=r"\d+(\.\d+)?",


def height_labels():
    """Contact heights as they appear in file names (mm, no trailing zeros)."""
    return [f"{h:g}" for h in config["heights_mm"]]


def object_geometry_files():
    return sorted(expand(
        f"{GEOMETRY}/objects/{{object}}_h{{height}}.npz",
        object=list(config["objects"]),
        height=height_labels(),
    ))


def polygon_file_input(wildcards):
    """The user's polygon file, so that editing it re-places the object."""
    spec = config["objects"][wildcards.object]
    return [spec["path"]] if spec["type"] == "polygon_file" else []


def object_spec(wildcards):
    """The object's shape (its split and materials do not change the geometry)."""
    spec = config["objects"][wildcards.object]
    return canonical({k: v for k, v in spec.items() if k not in ("split", "materials")})


def object_split(wildcards):
    return config["objects"][wildcards.object]["split"]


def object_splits():
    """Split of every object (name -> split)."""
    return canonical({n: s["split"] for n, s in config["objects"].items()})


def object_deformable(wildcards):
    """Objects simulated in any deformable material get a mesh; rigid ones do not."""
    return object_is_meshed(config, wildcards.object)


def material_params(wildcards):
    """The object material's constants, so that editing them re-runs its scenes."""
    return material_constants(wildcards.material)


def finger_fea_params():
    """What a scene reads of the finger besides its mesh: material name, extrusion (mm)."""
    return canonical({k: config["finger"][k] for k in ("material", "extrusion_mm")})


def study_materials(*extra):
    """Materials of an FEA study: steel, the finger's and ``extra`` (those configured)."""
    names = {"steel", config["finger"]["material"], *extra} & set(config["materials"])
    return canonical({n: material_constants(n) for n in names})


def fea_files(name, splits=None):
    """A file of every FEA scene (optionally of some splits only)."""
    return sorted(
        f"{FEA}/{s.object}/{s.material}/h{s.height_mm:g}/{name}"
        for s in scenes(config)
        if splits is None or s.split in splits
    )


def pitch_label(p):
    return f"{float(p):g}"


def rendered_views():
    """(scene, pitch) of every render: pitch 0 for all scenes, every pitch of
    render.pitches_deg for the pitch scene (pitch object, first material, middle
    height: the 3D renderer is much slower than the 2D one, so only where needed; both
    are timed in results/benchmarks/render_throughput.json)."""
    pobj, pmat, ph = pitch_scene()
    views = []
    for s in scenes(config):
        is_pitch_scene = (s.object, s.material, f"{s.height_mm:g}") == (pobj, pmat, ph)
        views += [(s, p) for p in (series_pitches() if is_pitch_scene else [0.0])]
    return views


def shard_files(splits=None, pitch=None, exclude_objects=()):
    """Shards of every rendered view (optionally of some splits, or one pitch only, less
    those of ``exclude_objects``), sorted: the order of the objects in the config does not
    change what a job reads."""
    return sorted(
        f"{DATASET}/shards/{s.object}/{s.material}/h{s.height_mm:g}/p{pitch_label(p)}.npz"
        for s, p in rendered_views()
        if (splits is None or s.split in splits) and (pitch is None or p == pitch)
        and s.object not in exclude_objects
    )


# The diversity comparison (generated.compare_model): (paper-objects model, model), or None
# where no generated object trains. The paper-objects model is the job a config without
# the generated objects runs for that model: the same params, the paper objects' shards.
DIVERSITY = diversity_models(config)
GENERATED_TRAIN = frozenset(generated_training_objects(config))


def trained_model(name):
    """The train.models entry a trained model follows (the paper-objects model: its model's)."""
    return DIVERSITY[1] if DIVERSITY and name == DIVERSITY[0] else name


def train_shards(wildcards):
    """A model's training shards (front views of the train split); the paper-objects model
    of the diversity comparison gets those of the non-generated objects only."""
    exclude = GENERATED_TRAIN if DIVERSITY and wildcards.model == DIVERSITY[0] else ()
    return shard_files(splits=["train"], pitch=0.0, exclude_objects=exclude)


def model_augment(wildcards):
    return canonical(config["train"]["models"][trained_model(wildcards.model)])


def model_names():
    """Names of train.models, sorted."""
    return sorted(config["train"]["models"])


def pitch_scene():
    """The pitch object, its first material and the middle contact height."""
    pobj = pitch_object(config)
    heights = sorted(config["heights_mm"])
    return pobj, config["objects"][pobj]["materials"][0], f"{heights[len(heights) // 2]:g}"


def series_pitches():
    """Pitches of the viewpoint series (deg): 0 and every one of render.pitches_deg."""
    return sorted({0.0} | {float(p) for p in config["render"]["pitches_deg"]})


def pitch_series_indices():
    """Render indices of the pitch scene at every pitch (the figure's series)."""
    obj, mat, h = pitch_scene()
    return [f"{RENDER}/{obj}/{mat}/h{h}/p{pitch_label(p)}/index.json" for p in series_pitches()]


def render_benchmark_input(wildcards):
    obj, mat, h = pitch_scene()
    return f"{FEA}/{obj}/{mat}/h{h}/result.npz"


def render_scene_params(wildcards):
    """Scene description copied into the render index (and from there into the shard)."""
    return canonical({
        "object": wildcards.object,
        "material": wildcards.material,
        "height_mm": float(wildcards.height),
        "split": config["objects"][wildcards.object]["split"],
    })


def scene_camera_views(wildcards):
    """render.camera_views for the front view of a training scene (the camera model's
    inputs), None for every other view."""
    views = config["render"]["camera_views"]
    train = config["objects"][wildcards.object]["split"] == "train"
    return canonical(views) if train and float(wildcards.pitch) == 0 and views["enabled"] else None


def shard_scene_params(wildcards):
    scene = render_scene_params(wildcards)
    is_pitch_object = wildcards.object == pitch_object(config)
    scene["splits"] = scene_splits(scene["split"], float(wildcards.pitch), is_pitch_object)
    return canonical(scene)


def model_file(name, train_dir=TRAIN):
    return f"{train_dir}/{name}/model.ts"


def eval_models(*names, train_dir=TRAIN):
    """The models an experiment compares (name -> TorchScript), those of the config only."""
    return {n: model_file(n, train_dir) for n in names if n in config["train"]["models"]}


# The spread study (spread.smk): a variant s<seed>_<type> retrains every model with that
# seed and numeric type (train.bf16: auto, fp32 = false, bf16 = true); s<seed>_<type>_<point>
# also with a point of the training-budget study (benchmarks.training_budget.points)
SPREAD = f"{RESULTS}/evaluate/spread"
SPREAD_TYPES = {"auto": "auto", "fp32": False, "bf16": True}


def train_dir(wildcards):
    """Where an experiment's models come from: the run's (results/train), or a seed
    variant's of the spread study (a ``variant`` wildcard, spread.smk)."""
    variant = getattr(wildcards, "variant", None)
    return f"{SPREAD}/{variant}/train" if variant else TRAIN


def spread_variant(seed, bf16, point=None):
    """The variant name of a seed, a train.bf16 value and a budget point (None: the run's)."""
    kind = {str(v).lower(): k for k, v in SPREAD_TYPES.items()}[str(bf16).lower()]
    return f"s{seed}_{kind}" + (f"_{point}" if point and point != "default" else "")


def spread_variants():
    """Every variant of evaluate.spread, seeds within each numeric type."""
    sp = config["evaluate"]["spread"]
    return [f"s{s}_{t}" for t in sp["types"] for s in sp["seeds"]]


def budget_points():
    """The training-budget study's points: "default" (the train section), then the config's."""
    return ["default"] + list(config["benchmarks"]["training_budget"]["points"])


def budget_variants():
    """point -> its variants (one per seed of benchmarks.training_budget, the run's bf16)."""
    seeds = config["benchmarks"]["training_budget"]["seeds"]
    return {p: [spread_variant(s, config["train"]["bf16"], p) for s in seeds] for p in budget_points()}


def spread_train_params(wildcards):
    """The run's train section with the variant's seed, bf16 and budget point."""
    seed, kind, *point = wildcards.variant[1:].split("_")
    over = config["benchmarks"]["training_budget"]["points"][point[0]] if point else {}
    return canonical({**section("train", drop=("models",)), **over, "seed": int(seed),
                      "bf16": SPREAD_TYPES[kind]})


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
        return {"shards": shard_files(splits=[e], pitch=0.0),
                "models": eval_models("plain", "camera", train_dir=d),
                "group_col": "object" if e == "shape" else "material", "conditions": None,
                "renders": render_index_files(pitch=0.0, splits=[e])}
    if e == "occlusion":
        return {"shards": shard_files(splits=["shape"], pitch=0.0),
                "models": eval_models("plain", "occlusion", train_dir=d), "group_col": "object",
                "conditions": [[lvl, {"occlusion": lvl}] for lvl in occlusion_level_order()],
                "renders": []}
    if e == "viewpoint":  # perspective renders of the held-out shapes (evaluate.viewpoint)
        return {"shards": shard_files(splits=["shape"], pitch=0.0),
                "models": eval_models("plain", "pitch", "camera", train_dir=d),
                "group_col": "distance_mm",
                "conditions": [[f"{p:g}", {"pitch_deg": p}] for p in series_pitches()],
                "renders": viewpoint_indices()}
    return {"shards": pitch_series_shards(), "models": eval_models("plain", "pitch", train_dir=d),
            "group_col": None,
            "conditions": [[f"{p:g}", {"pitch_deg": p}] for p in series_pitches()], "renders": []}


def viewpoint_indices():
    """index.json of the viewpoint experiment's renders: every held-out shape scene."""
    return sorted(f"{RENDER}/viewpoint/{s.object}/{s.material}/h{s.height_mm:g}/index.json"
                  for s in scenes(config) if s.split == "shape")


def experiment_params(wildcards):
    """Models (name, in the order compared), grouping and conditions (ordered [name,
    settings] pairs) of an experiment; the shards and model files are its inputs."""
    setup = experiment_setup(wildcards)
    return canonical({"models": list(setup["models"]), "group_col": setup["group_col"],
                      "conditions": setup["conditions"]})


def experiment_inputs(wildcards):
    """Test shards, model files (model.ts; its model.ts.json comes with it) and, for the
    camera path, the test views' render indices."""
    setup = experiment_setup(wildcards)
    return {"shards": setup["shards"], "models": list(setup["models"].values()),
            "renders": setup["renders"]}


def render_index_files(pitch=None, splits=None):
    """index.json of every rendered view (optionally of one pitch, or some splits only),
    sorted. A view's PNG + EXR files (render.files_per_scene) are written by the same
    job before its index, which names them: the index stands for them in the DAG (how
    many there are depends on the solver's frames, unknown before the FEA runs)."""
    return sorted(
        f"{RENDER}/{s.object}/{s.material}/h{s.height_mm:g}/p{pitch_label(p)}/index.json"
        for s, p in rendered_views()
        if (pitch is None or p == pitch) and (splits is None or s.split in splits)
    )


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
    ] + expand("paper/figures/{name}.pdf", name=FIGURES) + expand(
        f"{TRAIN}/{{model}}/model.ts", model=model_names()
    ) + object_geometry_files()


# ------------------------------------------------------------- the emulated lab rig
LAB = f"{RESULTS}/lab"


def sim2real_model(train_dir=TRAIN):
    """The network sim-to-real starts from: the camera model where configured, else plain."""
    return f"{train_dir}/{'camera' if 'camera' in config['train']['models'] else 'plain'}/model.pt"


def lab_takes():
    """Every take's name: <object>_h<height>."""
    return [f"{o}_h{h:g}" for o in sorted(config["lab"]["objects"]) for h in config["lab"]["heights_mm"]]


def lab_finger():
    return canonical(as_built_finger(config["finger"], config["lab"]["as_built"]))


def lab_object_spec(wildcards):
    return canonical(config["lab"]["objects"][wildcards.object])


def lab_polygon_input(wildcards):
    spec = config["lab"]["objects"][wildcards.object]
    return [spec["path"]] if spec["type"] == "polygon_file" else []


def lab_take_seed(wildcards):
    """The take's seed: lab.seed and its name (adding a take leaves the others alone)."""
    return config["lab"]["seed"] + zlib.crc32(f"{wildcards.object}_h{wildcards.height}".encode()) % 100000


# The diversity comparison (evaluate.smk's evaluate_diversity, DIVERSITY_DIR there)
def diversity_files():
    """The comparison's summary where the config plans it (generated training objects and
    generated.compare_model), else nothing."""
    return [f"{DIVERSITY_DIR}/summary.json"] if DIVERSITY else []


def _diversity_or_stop():
    if not DIVERSITY:
        raise ValueError(f"{DIVERSITY_DIR} needs generated training objects (generated.count > 0, "
                         "split train) and generated.compare_model: see config/diverse.yaml")
    return DIVERSITY


def diversity_inputs(wildcards):
    """Test shards of the shape and material experiments; both models and their histories."""
    paper, model = _diversity_or_stop()
    tests = {f"{t}_shards": experiment_setup(SimpleNamespace(experiment=t))["shards"]
             for t in DIVERSITY_TESTS}
    return {**tests, "models": [model_file(paper), model_file(model)],
            "histories": [f"{TRAIN}/{m}/history.json" for m in (paper, model)]}


def diversity_params(wildcards):
    """Grouping of each test set (as its experiment's), the models' names and the number
    of training objects of each (the paper's, and those plus the generated ones)."""
    paper, model = _diversity_or_stop()
    train = [n for n, o in config["objects"].items() if o["split"] == "train"]
    n_gen = sum(n in GENERATED_TRAIN for n in train)
    return canonical({
        "tests": {t: experiment_setup(SimpleNamespace(experiment=t))["group_col"] for t in DIVERSITY_TESTS},
        "setup": {"model": model, "models": {"paper_objects": paper, "with_generated": model},
                  "n_generated": n_gen,
                  "train_objects": {"paper_objects": len(train) - n_gen, "with_generated": len(train)}}})
