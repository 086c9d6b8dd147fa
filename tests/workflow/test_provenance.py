"""Provenance: a changed config value re-plans exactly the jobs that read it.

How the plan is obtained (Snakemake's own, without running a job): the module fixture
fakes a finished smoke run in a temporary working directory. Snakemake builds the smoke
config's DAG, every output (and benchmark file) is touched in topological order, and
Snakemake's persistence records each job's metadata as after a real run
(``Persistence.finished``: params, set of input files, code, software stack); the smoke
config then plans nothing. For every leaf key of the schema (for ``objects``,
``materials`` and ``train.models``: the entries of config/smoke.yaml), a copy of the
smoke config with that one value changed is planned: the DAG ``snakemake -n`` builds,
with all rerun triggers. Two views of it are compared with ``READERS``:

- readers: the rules whose jobs see the change by Snakemake's own checks
  (``params_changed``, ``input_changed``), asked of every job, or that get new jobs;
  these must equal the key's entry in ``READERS`` (``UNREAD``: none);
- first: the rules Snakemake re-plans on their own account (not merely because an
  upstream job reruns); they must be among the readers, and not empty. Snakemake checks
  a job's params only when nothing upstream reruns, so this is the first stage that
  reads the value.

The test fails if a rule stops declaring a value its script reads: its recorded and new
params then agree, the rule drops out of the key's readers and differs from
``READERS`` (a script cannot read the config past its params and input:
``test_no_script_reads_config``). It fails too if a rule declares a value it does not
read (it shows up under a key it does not read), if a key no job reads is not listed in
``UNREAD`` with its reason, and if the same config with its keys in another order
re-plans anything (params not in canonical form).

One DAG per key (~0.2-0.5 s each), built in this process with Snakemake's internal
``Workflow._prepare_dag``/``_build_dag`` and ``persistence`` (Snakemake 9).
"""

from __future__ import annotations

import copy
import fnmatch
import os
import time
from pathlib import Path

import pytest
import yaml

snakemake_api = pytest.importorskip("snakemake.api")
from snakemake.settings.types import (  # noqa: E402
    ConfigSettings,
    DAGSettings,
    ExecutionSettings,
    OutputSettings,
    Quietness,
    ResourceSettings,
)

from finray.config import (  # noqa: E402
    load_schema,
    merge_config,
    object_heights,
    read_config_file,
    validate_config,
)

from helpers import ROOT  # noqa: E402

pytestmark = [pytest.mark.slow, pytest.mark.workflow]  # not in `pytest -m "not slow"`

SMOKE = ROOT / "config" / "smoke.yaml"
SCHEMA = ROOT / "workflow" / "schemas" / "config.schema.yaml"
#: mappings whose entries are the user's (walked from the smoke config, not the schema)
MAPS = {("objects",), ("materials",), ("train", "models"), ("lab", "objects")}

# ------------------------------------------------------------------------- readers
#: key pattern (fnmatch, first match wins) -> every rule whose jobs see a change of it:
#: their params change, their set of input files changes, or the change adds jobs of
#: that rule. Downstream rules that merely get updated input files are not listed.
_STUDIES = {"fea_pareto", "fea_stability"}
_LAB_GEOMETRY = {"lab_finger", "lab_object"}  # the emulated rig's as-built finger
_PRIOR_GEOMETRY = {"rig_prior_finger", "rig_prior_object"}  # the rig prior's thicker walls
_GEOMETRY = {"geometry_finger", "geometry_object"} | _STUDIES | _LAB_GEOMETRY | _PRIOR_GEOMETRY
_RENDER = {"render_scene", "render_benchmark"}
_SEGMENT = _RENDER | {"dataset_examples", "train_model"}  # crop and segmentation
#: what renders with the render settings: also the viewpoint experiment's perspective renders
_RENDERS = _RENDER | {"viewpoint_render"}
#: what lists every scene or every training shard (a new or moved scene changes its input)
#: what a training object's scenes at extra_train_heights_mm change (the smoke config has one)
_EXTRA_HEIGHT = {"dataset_manifest", "fea_figures", "inference_latency", "sim2real_no_context"}
_LISTS = {
    "fea_figures",
    "dataset_manifest",
    "evaluate_baseline",
    "train_model",
    "train_pareto",
    "inference_latency",
    "sim2real_no_context",
}
READERS: list[tuple[str, set[str]]] = [
    ("finger.material", _GEOMETRY | {"fea_scene", "summary", "lab_fea", "rig_prior_fea"}),
    (
        "finger.extrusion_mm",
        _GEOMETRY
        | _RENDERS
        | {
            "fea_scene",
            "train_model",
            "evaluate_experiment",
            "summary",
            "lab_fea",
            "lab_take",
            "rig_prior_fea",
        },
    ),
    ("finger.base_width_mm", _GEOMETRY | {"train_model", "lab_ingest", "render_scene"}),
    ("finger.ribs.count", _GEOMETRY | {"summary"}),
    ("finger.ribs.angle_step_deg", _GEOMETRY | {"summary"}),
    ("finger.*", _GEOMETRY),
    ("mesh.size_mm", _GEOMETRY | {"summary"}),
    ("mesh.min_angle_deg", _GEOMETRY),
    (
        "mesh.*",
        {"geometry_finger", "lab_finger", "rig_prior_finger"} | _STUDIES,
    ),  # order, arc chords: the finger only
    ("placement.gap_mm", {"geometry_object", "rig_prior_object"} | _STUDIES),
    (
        "heights_mm",
        {
            "geometry_object",
            "fea_scene",
            "render_scene",
            "geometry_gallery",
            "viewpoint_render",
            "dataset_examples",
            "evaluate_experiment",
            "figure_material_generalisation",
            "render_benchmark",
            "summary",
        }
        | _LISTS,
    ),
    # new training scenes, and the model that trains on them (sim-to-real's no-context fit
    # reads the camera model's training shards)
    # (and the experiments, which tell the training's heights from the unseen ones)
    (
        "extra_train_heights_mm",
        {
            "geometry_object",
            "fea_scene",
            "render_scene",
            "dataset_manifest",
            "fea_figures",
            "train_model",
            "sim2real_no_context",
            "inference_latency",
            "evaluate_experiment",
        },
    ),
    # the face heights: new scenes of that split (new jobs, and every list of scenes or
    # shards); the experiments tell their heights from the training's (train)
    (
        "face_heights_mm.train",
        {"geometry_object", "fea_scene", "render_scene", "evaluate_experiment"} | _LISTS,
    ),
    (
        "face_heights_mm.shape",
        {
            "geometry_object",
            "fea_scene",
            "render_scene",
            "evaluate_experiment",
            "dataset_manifest",
            "fea_figures",
            "sim2real_no_context",
            "inference_latency",
        },
    ),
    # (the rig prior: its wall variants' friction, and the nominal its gains are against)
    ("fea.friction", {"fea_scene", "summary", "rig_prior_fea", "rig_prior"} | _STUDIES),
    ("fea.push_mm", {"fea_scene", "summary", "rig_prior_fea"} | _STUDIES),
    (
        "fea.*",
        {"fea_scene", "lab_fea", "rig_prior_fea"} | _STUDIES,
    ),  # (friction and push: the lab's own)
    (
        "render.pitches_deg",
        {
            "render_scene",
            "dataset_manifest",
            "dataset_examples",
            "evaluate_experiment",
            "viewpoint_render",
        },
    ),  # the new pitch's views
    ("render.window_y_mm", _RENDERS | {"train_model", "evaluate_experiment"}),  # pitch axis
    # the training scenes' camera views (and the manuscript quotes them)
    ("render.camera_views.*", {"render_scene", "summary"}),
    ("render.*", _RENDERS),
    ("dataset.sizes", _RENDER | {"lab_ingest"}),
    ("dataset.crop_y_mm", _SEGMENT | {"evaluate_experiment", "lab_ingest"}),
    ("dataset.crop_x_mm", _SEGMENT | {"lab_ingest"}),
    (
        "dataset.occlusion_levels",
        {"dataset_examples", "train_model", "evaluate_experiment", "summary"},
    ),  # the manuscript quotes them
    ("dataset.noise_levels", {"dataset_examples"}),
    ("dataset.occluder_value", {"dataset_examples"}),
    (
        "dataset.pitch_object",
        {
            "render_scene",
            "render_benchmark",
            "dataset_manifest",
            "dataset_examples",
            "evaluate_experiment",
        },
    ),
    (
        "dataset.base_band",
        _RENDER | {"train_model", "lab_ingest"},
    ),  # camera views' crop, the predictor's
    ("dataset.*", _SEGMENT),
    (
        "train.input_size",
        {
            "train_model",
            "train_pareto",
            "evaluate_baseline",
            "evaluate_experiment",
            "summary",
            "lab_qa",
            "sim2real",
            "sim2real_no_context",
        },
    ),
    ("train.base_channels", {"train_model", "train_pareto", "summary"}),
    # how a model trains (another's weights, its own epochs): the manuscript says it
    ("train.models.*.start_from", {"train_model", "summary"}),
    ("train.models.*.epochs", {"train_model", "summary"}),
    ("train.models.*", {"train_model"}),
    ("train.epochs", {"train_model", "summary"}),
    (
        "train.frame_every",
        {"train_model"},
    ),  # (the network study reads its own benchmarks.train_every)
    ("train.lr", {"train_model"}),
    ("train.alpha_*", {"train_model", "summary"}),  # the manuscript states the loss
    ("train.contact_*", {"train_model"}),  # the contact head (the studies train without it)
    (
        "train.force_*",
        {"train_model"},
    ),  # the force term's weights (the network study's are its own)
    ("train.batch_size", {"train_model", "train_pareto", "summary"}),
    ("train.forces", {"train_model"}),
    ("train.device", {"train_model"}),  # not the CPU study (train_pareto)
    ("train.init", {"train_model", "summary"}),  # the manuscript states the init
    ("train.split_seed", {"train_model"}),
    ("train.*", {"train_model", "train_pareto"}),
    ("evaluate.seed", {"evaluate_baseline", "evaluate_experiment"}),
    ("evaluate.usable_nrmse_pct", {"figure_viewpoint", "summary"}),
    ("evaluate.viewpoint.*", {"viewpoint_render", "summary"}),
    # the rig prior's FEA: its variants (new jobs), the prior's draws
    (
        "evaluate.sim2real.rig_prior.gain.thickness_delta_mm",
        {"rig_prior", "rig_prior_finger", "rig_prior_object", "rig_prior_fea"},
    ),
    ("evaluate.sim2real.rig_prior.gain.friction", {"rig_prior", "rig_prior_fea"}),
    # (a scene the training lacks: its nominal FEA too)
    (
        "evaluate.sim2real.rig_prior.gain.scenes",
        {"rig_prior", "rig_prior_object", "rig_prior_fea", "geometry_object", "fea_scene"},
    ),
    ("evaluate.sim2real.rig_prior.gain.*", {"rig_prior"}),
    # the no-context fit (the simulation's, every rig's) and the context fits
    ("evaluate.sim2real.sim_every", {"sim2real_no_context"}),
    ("evaluate.sim2real.sim_folds", {"sim2real_no_context"}),
    ("evaluate.sim2real.sim_views", {"sim2real_no_context"}),
    ("evaluate.sim2real.heads.*", {"sim2real_no_context", "sim2real"}),
    ("evaluate.sim2real.priors.*", {"sim2real_no_context", "sim2real"}),
    ("evaluate.sim2real.sampler.*", {"sim2real_no_context", "sim2real"}),
    ("evaluate.sim2real.level", {"sim2real_no_context", "sim2real"}),
    ("evaluate.sim2real.*", {"sim2real"}),
    # the manuscript quotes the spread study: the summary waits for it, so its jobs join the DAG
    # (and the face figure draws a line per variant)
    (
        "evaluate.spread.manuscript",
        {
            "summary",
            "spread_train",
            "spread_experiment",
            "spread_sim2real",
            "spread_sim2real_no_context",
            "spread_summary",
            "figure_face",
        },
    ),
    ("benchmarks.fea_*", _STUDIES),
    ("benchmarks.latency_model", {"inference_latency"}),
    # the live-stream benchmark's model also draws the annotated figure, at its pitch
    ("benchmarks.realtime_model", {"realtime_benchmark", "figure_annotated"}),
    ("benchmarks.realtime_pitch_deg", {"realtime_benchmark", "figure_annotated"}),
    ("benchmarks.realtime_*", {"realtime_benchmark"}),
    ("benchmarks.latency_frames", {"inference_latency", "train_pareto"}),
    ("benchmarks.latency_repeats", {"inference_latency"}),
    ("benchmarks.train_*", {"train_pareto"}),
    # the finger's material: every scene (and the studies, which use it too)
    (
        "materials.ninjaflex.youngs_modulus_MPa",
        {"fea_scene", "summary", "lab_fea", "rig_prior_fea"} | _STUDIES,
    ),
    ("materials.ninjaflex.*", {"fea_scene", "lab_fea", "rig_prior_fea"} | _STUDIES),
    ("materials.neoprene.rigid", {"geometry_object", "fea_scene", "fea_stability"}),
    ("materials.neoprene.*", {"fea_scene", "fea_stability"}),
    ("materials.steel.rigid", {"geometry_object", "fea_scene"} | _STUDIES),
    # where an object's scenes go: its scenes, and what lists the splits' shards; into or
    # out of training, its scenes at the smoke config's extra training height come or go
    # (what lists every scene, and the camera model's shards)
    # (a split's face heights: its objects at other heights, new geometry too)
    (
        "objects.circle_d10.split",
        _EXTRA_HEIGHT
        | {
            "geometry_object",
            "fea_scene",
            "render_scene",
            "geometry_gallery",
            "dataset_examples",
            "dataset_manifest",
            "evaluate_baseline",
            "evaluate_experiment",
            "render_benchmark",
            "train_model",
            "train_pareto",
            "viewpoint_render",
            # the first held-out shape: the live-stream benchmark's
            # and the annotated figure's renders
            "realtime_benchmark",
            "figure_annotated",
        },
    ),  # it becomes the pitch object
    (
        "objects.square_s10_a30.split",
        _EXTRA_HEIGHT
        | {
            "fea_scene",
            "render_scene",
            "geometry_gallery",
            "evaluate_baseline",
            "evaluate_experiment",
            "train_model",
            "train_pareto",
            "figure_material_generalisation",
            "sim2real_no_context",
        },
    ),
    (
        "objects.ring_d15.split",
        _EXTRA_HEIGHT
        | {
            "geometry_object",
            "fea_scene",
            "render_scene",
            "geometry_gallery",
            "evaluate_baseline",
            "evaluate_experiment",
            "train_model",
            "train_pareto",
            "figure_material_generalisation",
            "sim2real_no_context",
        },
    ),
    (
        "objects.ellipse_16x9.split",
        {
            "fea_scene",
            "render_scene",
            "geometry_gallery",
            "dataset_manifest",
            "fea_figures",
            "inference_latency",
            "evaluate_experiment",
            "figure_material_generalisation",
            "sim2real_no_context",
            "realtime_benchmark",
            "figure_annotated",
        },
    ),
    # its materials: a deformable one meshes the object; new scenes (train objects: in
    # the training lists), removed ones (the lists lose them)
    (
        "objects.ring_d15.materials",
        {
            "geometry_object",
            "dataset_manifest",
            "evaluate_experiment",
            "fea_figures",
            "figure_material_generalisation",
            "inference_latency",
        },
    ),
    (
        "objects.ellipse_16x9.materials",
        {
            "geometry_object",
            "fea_scene",
            "render_scene",
            "dataset_manifest",
            "evaluate_experiment",
            "fea_figures",
            "inference_latency",
            "viewpoint_render",
            "sim2real_no_context",
            "realtime_benchmark",
            "figure_annotated",
        },
    ),
    ("objects.*.materials", {"geometry_object", "fea_scene", "render_scene"} | _LISTS),
    (
        "objects.circle_d10.*",
        {"geometry_object", "rig_prior_object"},
    ),  # the rig prior's scene (smoke)
    ("objects.*", {"geometry_object"}),  # the shape
    # one generated object more: its scenes, and what lists the training scenes
    # (and, as a generated object now trains, the diversity comparison: the paper-objects
    # model is a new train_model job; its evaluation feeds the summary and the speed table)
    (
        "generated.count",
        {
            "geometry_object",
            "fea_scene",
            "render_scene",
            "geometry_gallery",
            "evaluate_diversity",
            "evaluate_speed",
            "summary",
        }
        | _LISTS,
    ),
    # the emulated lab rig: read by the lab's rules only (never by training or predict)
    # the drawn rigs (lab.rigs): one more rig is every rig rule's; the others change what
    # is drawn (a height's jitter renames the takes: new jobs, not re-planned ones)
    (
        "lab.rigs.count",
        {
            "rig_finger",
            "rig_object",
            "rig_fea",
            "rig_take",
            "rig_ingest",
            "rig_sim2real",
            "sim2real_rigs",
        },
    ),
    ("lab.rigs.colours.*", {"rig_take"}),
    ("lab.rigs.object_scale", {"rig_object"}),
    ("lab.rigs.height_jitter_mm", {"sim2real_rigs"}),
    # (heights over the face: the rig's objects, FEA, takes and their sim-to-real anew)
    (
        "lab.rigs.height_span_mm",
        {"rig_object", "rig_fea", "rig_take", "rig_ingest", "rig_sim2real", "sim2real_rigs"},
    ),
    ("lab.rigs.*", {"rig_take", "sim2real_rigs"}),  # seed, uniform, choice: the camera's draws
    ("lab.camera.model", {"lab_take", "summary"}),  # a drawn rig names its own
    ("lab.seed", {"lab_take"}),
    ("lab.objects.*", {"lab_object"}),  # the shape
    # (the annotated figure draws the first take: an evaluation, like sim2real)
    (
        "lab.heights_mm",
        {
            "lab_object",
            "lab_fea",
            "lab_take",
            "lab_ingest",
            "lab_qa",
            "sim2real",
            "figure_annotated",
        },
    ),
    # (the summary quotes how the takes were emulated: as built, motion, camera, sensor)
    ("lab.as_built.thickness_delta_mm", _LAB_GEOMETRY | {"summary"}),
    # the print's time dependence: the sensor's log of the takes (the image follows the push)
    ("lab.as_built.viscoelastic", {"lab_take", "summary"}),
    ("lab.as_built.relax_*", {"lab_take", "summary"}),
    ("lab.as_built.softening", {"lab_take", "summary"}),
    ("lab.as_built.*", {"lab_fea", "summary"}),
    ("lab.motion.gap_mm", {"lab_object", "lab_take", "summary"}),
    ("lab.motion.push_mm", {"lab_fea", "lab_take", "summary"}),
    ("lab.look.*", {"lab_take"}),
    ("lab.*", {"lab_take", "summary"}),  # motion, camera, sensor
]

#: keys no job reads, with the reason (a change re-plans nothing)
UNREAD = {
    "materials.ninjaflex.source": "documentation of the constants only",
    "materials.neoprene.source": "documentation of the constants only",
    # the spread study is a target of its own (spread.smk), not in the default run's DAG;
    # test_workflow.py::test_smoke_spread runs it
    "evaluate.spread.seeds": "read by the spread study only (results/evaluate/spread/)",
    "evaluate.spread.types": "read by the spread study only (results/evaluate/spread/)",
    "evaluate.spread.models": "read by the spread and training-budget studies only",
    "lab.rigs.selection": "read by the selection rigs' target only (results/evaluate/sim2real/rigs/selection/)",
    "benchmarks.training_budget.seeds": "read by the training-budget study only (its own target)",
    "benchmarks.training_budget.points": "read by the training-budget study only (its own target)",
    **{
        f"benchmarks.fea_sweep.{k}": "read by the FEA sweep only (its own target, "
        "results/benchmarks/fea_sweep/summary.md)"
        for k in (
            "count",
            "seed",
            "batches",
            "circle_diameter_mm",
            "square_side_mm",
            "ellipse_axis_mm",
            "polygon_radius_mm",
            "height_max_mm",
        )
    },
    # (tests/workflow/test_config.py::test_generated_keys_are_in_every_blob_spec: each reaches the
    # objects entry of every generated object, whose provenance is that of objects.*)
    **{
        f"generated.{k}": "the smoke config generates no objects (generated.count 0)"
        for k in (
            "seed",
            "size_mm",
            "harmonics",
            "amplitude",
            "split",
            "materials",
            "compare_model",
        )
    },
}

#: keys that cannot change alone (the config is refused), with the expected message
REFUSED = {
    "materials.ninjaflex.rigid": "finger.material: the finger cannot be rigid",
}


def _with_wall(spec):
    spec.update(type="ring", wall_mm=2.0)


#: the new value of a key where the generic change (numbers x0.95 or +1, booleans
#: flipped, last list item changed) is invalid or says nothing; a callable edits the
#: config (a key the schema then requires comes with it)
NEW_VALUES = {
    "train.force_loss": "absolute",
    "extra_train_heights_mm": {"camera": [16.0]},
    "lab.rigs.height_span_mm": [12.0, 70.0],
    "finger.material": "neoprene",
    "finger.ribs.count": 10,
    "mesh.order": 1,
    "render.window_x_mm": [-5.0, 36.0],
    "render.window_y_mm": [-2.0, 83.0],
    "render.px_per_mm": 5.0,
    "render.frames_per_scene": 30,
    "dataset.sizes": [[128, 64], [64, 32], [32, 16]],
    "evaluate.sim2real.folds": "take",
    "evaluate.sim2real.sim_views": "camera",
    "benchmarks.training_budget.points": {"f3": {"frame_every": 3}},
    "dataset.crop_x_mm": [-4.0, 36.0],
    "dataset.crop_y_mm": [1.0, 81.0],
    "dataset.threshold": "otsu",
    "dataset.foreground": "dark",
    "dataset.noise_levels": {"none": 0.0, "low": 0.02, "medium": 0.05, "high": 0.12},
    "dataset.occlusion_levels": {
        "none": [0, 0],
        "low": [0.1, 0.3],
        "medium": [0.4, 0.8],
        "high": [0.8, 0.9],
    },
    "dataset.occluder_value": 0.5,
    "dataset.pitch_object": "ring_d15",
    "generated.split": "shape",
    "generated.materials": ["steel", "neoprene"],
    "generated.compare_model": "occlusion",
    "train.models.occlusion.start_from": "camera",
    "train.input_size": [128, 64],
    "train.forces": ["fx"],
    "train.bf16": False,
    "train.device": "cpu",
    "train.schedule": "constant",
    "train.keep": "last",
    "train.init": "torch",
    "evaluate.spread.types": ["fp32"],
    "evaluate.spread.models": ["camera"],
    "benchmarks.fea_arc_chord_sizes_mm": [0.05],
    "benchmarks.train_sizes": [[64, 32]],
    "benchmarks.latency_model": "occlusion",
    "benchmarks.realtime_model": "plain",
    "materials.steel.rigid": lambda cfg: cfg["materials"]["steel"].update(
        rigid=False, youngs_modulus_MPa=2e5, poisson_ratio=0.3
    ),
    "objects.circle_d10.type": lambda cfg: _with_wall(cfg["objects"]["circle_d10"]),
    "objects.square_s10_a30.type": lambda cfg: cfg["objects"]["square_s10_a30"].update(
        type="circle", diameter_mm=10.0
    ),
    "objects.ring_d15.type": "circle",
    "objects.ellipse_16x9.type": lambda cfg: cfg["objects"]["ellipse_16x9"].update(
        type="circle", diameter_mm=12.0
    ),
    "objects.circle_d10.split": "shape",
    "objects.square_s10_a30.split": "material",
    "objects.ring_d15.split": "train",
    "objects.ellipse_16x9.split": lambda cfg: (
        cfg["objects"]["ellipse_16x9"].update(split="material"),
        cfg.setdefault("dataset", {}).update(pitch_object="ellipse_16x9"),
    ),
    "objects.circle_d10.materials": ["steel", "neoprene"],
    "objects.square_s10_a30.materials": ["steel", "neoprene"],
    "objects.ring_d15.materials": ["steel"],
    "objects.ellipse_16x9.materials": ["steel", "neoprene"],
    "lab.objects.cylinder.type": lambda cfg: cfg["lab"]["objects"]["cylinder"].update(
        type="square", side_mm=15.0
    ),
    "lab.look.finger_colour": "orange",
    "lab.look.clutter": [{"kind": "hand", "centre_mm": [30.0, 20.0], "size_mm": [20.0, 40.0]}],
    "lab.look.lights": [{"position_mm": [-200.0, 300.0, 300.0], "intensity": 0.8}],
    "lab.camera.video_pix_fmt": "yuv420p",
    "lab.rigs.uniform": {"camera.distance_mm": [180.0, 240.0]},
    "lab.rigs.choice": {"camera.size_px": [[1280, 720], [848, 480]]},
    "lab.rigs.object_scale": [0.9, 1.1],
    **{
        f"lab.rigs.colours.{k}": lambda cfg: (
            cfg["lab"]
            .setdefault("rigs", {})
            .update(
                colours={
                    "finger_hue_deg": [0.0, 360.0],
                    "object_hue_offset_deg": [120.0, 240.0],
                    "saturation": [0.6, 0.95],
                    "value": [0.5, 0.95],
                    "background_grey": [0.15, 0.5],
                }
            )
        )
        for k in (
            "finger_hue_deg",
            "object_hue_offset_deg",
            "saturation",
            "value",
            "background_grey",
        )
    },
}


# ------------------------------------------------------------------------- helpers
def _get(d, path):
    for k in path:
        d = d[k]
    return d


def leaf_keys(schema: dict, full: dict) -> list[tuple[str, ...]]:
    """Every leaf key of the schema; the entries of ``MAPS`` from ``full`` (the smoke
    config with defaults)."""
    out = []

    def walk(node, path):
        if tuple(path) in MAPS:
            out.extend((*path, name, k) for name, entry in _get(full, path).items() for k in entry)
        elif node.get("properties"):
            for k, sub in node["properties"].items():
                walk(sub, [*path, k])
        else:
            out.append(tuple(path))

    walk(schema, [])
    return out


def _generic(value):
    if isinstance(value, bool):
        return not value
    if isinstance(value, int):
        return value + 1
    if isinstance(value, float):
        return round(value * 0.95, 9) if value else 0.01
    if isinstance(value, str):  # a free text (an enum's keys are in NEW_VALUES)
        return value + " (edited)"
    if isinstance(value, list) and value:
        return value[:-1] + [_generic(value[-1])]
    raise AssertionError(f"no generic change for {value!r}: add the key to NEW_VALUES")


def changed_config(raw: dict, full: dict, key: tuple[str, ...]) -> dict:
    """Copy of the config file's ``raw`` dict with ``key`` changed (``full``: with defaults)."""
    cfg = copy.deepcopy(raw)
    new = NEW_VALUES.get(".".join(key), None)
    if callable(new):
        for k in key[:1]:  # the section the callable edits must be in the file
            cfg.setdefault(k, copy.deepcopy(full[k]) if k in MAPS else {})
        if key[0] in ("objects", "materials"):
            cfg[key[0]] = copy.deepcopy(full[key[0]])
        new(cfg)
        return cfg
    if new is None:
        new = _generic(_get(full, key))
    d = cfg
    for i, k in enumerate(key[:-1]):
        if k not in d:  # a section the smoke config leaves at its defaults
            d[k] = copy.deepcopy(_get(full, key[: i + 1]))
        d = d[k]
    d[key[-1]] = new
    return cfg


def reordered(d):
    """``d`` with every mapping's keys in reverse order (values unchanged)."""
    if isinstance(d, dict):
        return {k: reordered(d[k]) for k in reversed(list(d))}
    if isinstance(d, list):
        return [reordered(v) for v in d]
    return d


#: what the planner builds: the default run and the studies it built before they had
#: their own home (studies/<name>/), whose provenance stays checked here; the seeds,
#: training-budget and sweep studies were never planned (``UNREAD``)
TARGETS = frozenset(
    {"all", "fea_cost", "fea_stability", "render_throughput", "network_size", "realtime"}
)


class Planner:
    """Snakemake's DAG of the workflow for a config file, in a fixed working directory."""

    def __init__(self, workdir: Path):
        self.workdir = workdir

    def _build(self, api, configfile: Path | list[Path]):
        files = list(configfile) if isinstance(configfile, (list, tuple)) else [configfile]
        wf = api.workflow(
            ResourceSettings(cores=1),
            ConfigSettings(configfiles=files),
            snakefile=ROOT / "workflow" / "Snakefile",
            workdir=self.workdir,
        )
        wf.dag(DAGSettings(targets=TARGETS))
        w = wf._workflow
        w._prepare_dag(forceall=False, ignore_incomplete=False, lock_warn_only=True, nolock=True)
        w._build_dag()
        return w

    def _run(self, fn, configfile):
        cwd = os.getcwd()
        try:
            with snakemake_api.SnakemakeApi(OutputSettings(quiet={Quietness.ALL})) as api:
                return fn(self._build(api, configfile))
        finally:
            os.chdir(cwd)

    def complete(self, configfile: Path) -> int:
        """Fake a finished run of ``configfile``: outputs touched in topological order,
        metadata recorded by Snakemake; returns the number of jobs."""

        def fn(w):
            w.execution_settings = ExecutionSettings()
            t, n = time.time(), 0
            for level in w.dag.toposorted():
                t += 1
                for job in level:
                    for f in [*job.output, *([job.benchmark] if job.benchmark else [])]:
                        p = self.workdir / str(f)
                        p.parent.mkdir(parents=True, exist_ok=True)
                        p.touch()
                        os.utime(p, (t, t))
                    w.async_run(w.persistence.finished(job))
                    n += 1
            return n

        return self._run(fn, configfile)

    def plan(self, configfile: Path) -> tuple[dict[str, set[str]], set[str]]:
        """What Snakemake sees changed against the finished run, and what it re-plans.

        Returns ``readers``: rule -> why its jobs see the change (``params`` or ``input``
        set changed, by Snakemake's own checks on every job; ``new``: a job the change
        adds), and ``first``: the rules Snakemake re-plans on their own account (params,
        input set, code or software changed, output missing). Snakemake checks a job's
        params only when no upstream job reruns, so ``first`` holds the first stage
        that reads the change and ``readers`` every stage that does.
        """

        def fn(w):
            p, readers, first = w.persistence, {}, set()
            for job in w.dag.jobs:
                if not job.output:  # all and the studies' targets (fea_stability is its own)
                    continue
                why = {"params"} if p.params_changed(job) else set()
                if any(p.input_changed(job)):
                    why.add("input")
                if all(p.metadata(f) is None for f in job.output):
                    why.add("new")
                if why:
                    readers.setdefault(job.rule.name, set()).update(why)
            for job in w.dag.needrun_jobs():
                r = w.dag.reason(job)
                if job.output and (r.is_provenance_triggered() or r._missing_output):
                    first.add(job.rule.name)
            return readers, first

        return self._run(fn, configfile)

    def jobs(self, configfile: Path) -> dict[str, list[str]]:
        """Rule -> its jobs' first outputs."""

        def fn(w):
            out: dict[str, list[str]] = {}
            for job in w.dag.jobs:
                if job.output:
                    out.setdefault(job.rule.name, []).append(str(job.output[0]))
            return out

        return self._run(fn, configfile)


# ------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module", autouse=True)
def _schema_once():
    """Every plan validates a config: read the schema once (pure-Python YAML, ~0.3 s)."""
    import finray.config

    schema = finray.config.load_schema()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(finray.config, "load_schema", lambda: schema)
        yield


@pytest.fixture(scope="module")
def smoke():
    raw = yaml.safe_load(SMOKE.read_text())
    return raw, validate_config(raw, base_dir=ROOT)


@pytest.fixture(scope="module")
def planner(tmp_path_factory, smoke):
    wd = tmp_path_factory.mktemp("provenance")
    p = Planner(wd)
    # twice: the product reads a study's results where they exist (built(...) in the
    # rules: the summary, the speed table, the manuscript), so the second run's DAG is
    # the one a finished run of both has
    p.complete(SMOKE)
    n = p.complete(SMOKE)
    assert n > 50
    assert p.plan(SMOKE) == ({}, set()), "a finished run of the smoke config re-plans nothing"
    return p


def _write(tmp_path: Path, name: str, cfg: dict) -> Path:
    f = tmp_path / f"{name}.yaml"
    f.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return f


#: what sim2real_rigs records of each drawn rig (its params): how the rig was emulated
_RIG_RECORD = ("lab.as_built.*", "lab.camera.*", "lab.heights_mm")


def with_rigs(key: str, rules: set[str]) -> set[str]:
    """The drawn rigs (lab.rigs; the smoke config draws one, with no ranges: a copy of
    the lab) run the lab's rules and sim-to-real again: what one of those reads, the
    rig's copy reads too."""
    if key.startswith("lab.rigs.") or key == "lab.camera.model":
        return set(rules)
    out = set(rules) | {"rig_" + r[4:] for r in rules if r.startswith("lab_") and r != "lab_qa"}
    if "sim2real" in rules:
        out.add("rig_sim2real")
    if any(fnmatch.fnmatchcase(key, p) for p in _RIG_RECORD):
        out.add("sim2real_rigs")
    return out


def expected_readers(key: str) -> set[str]:
    for pattern, rules in READERS:
        if fnmatch.fnmatchcase(key, pattern):
            return with_rigs(key, rules)
    raise AssertionError(f"{key}: no entry in READERS")


# ------------------------------------------------------------------------- tests
def test_no_script_reads_config():
    """Scripts read their params and input only (Snakemake does not track snakemake.config)."""
    scripts = [*(ROOT / "workflow" / "scripts").glob("*.py"), *(ROOT / "studies").glob("*/*.py")]
    hits = [
        f"{p.name}:{i}"
        for p in sorted(scripts)
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if "snakemake.config" in line
    ]
    assert hits == []


def test_reordered_keys_replan_nothing(planner, smoke, tmp_path):
    """The same config with every mapping's keys in another order changes no job's params."""
    raw, _ = smoke
    f = _write(tmp_path, "reordered", reordered(raw))
    assert f.read_text() != yaml.safe_dump(raw, sort_keys=False)
    assert planner.plan(f) == ({}, set())


def test_every_key_replans_its_first_readers(planner, smoke, tmp_path):
    """Each leaf key, changed alone, re-plans exactly the rules of ``READERS`` (or
    nothing, for ``UNREAD``; or is refused, for ``REFUSED``)."""
    raw, full = smoke
    keys = leaf_keys(yaml.safe_load(SCHEMA.read_text()) if SCHEMA.exists() else load_schema(), full)
    assert len(keys) > 100
    assert set(UNREAD) | set(REFUSED) <= {".".join(k) for k in keys}
    got, wrong = {}, []
    only = os.environ.get("FINRAY_PROVENANCE_KEYS")  # comma-separated fnmatch patterns (debugging)
    if only:
        keys = [k for k in keys if any(fnmatch.fnmatch(".".join(k), p) for p in only.split(","))]
    for key in keys:
        name = ".".join(key)
        cfg = changed_config(raw, full, key)
        if name in REFUSED:
            with pytest.raises(Exception, match=REFUSED[name]):
                validate_config(cfg, base_dir=ROOT)
            continue
        validate_config(cfg, base_dir=ROOT)  # a clear message if the change itself is invalid
        readers, first = planner.plan(_write(tmp_path, name, cfg))
        got[name] = set(readers)
        want = set() if name in UNREAD else expected_readers(name)
        if got[name] != want:
            wrong.append(f"{name}: seen by {sorted(got[name])}, expected {sorted(want)}")
        elif want and not (first and first <= want):
            wrong.append(f"{name}: Snakemake re-plans {sorted(first)} first, not its readers")
    assert not wrong, "\n".join(wrong)


def test_named_mappings(planner, smoke, tmp_path):
    """The issue's cases, job by job: the finger's E re-plans every FEA scene (params),
    placement.gap_mm every object, mesh.* the finger, render.* every render, train.*
    every model."""
    raw, full = smoke
    jobs = planner.jobs(SMOKE)

    def replanned(key, rule, any_reason=False):
        f = _write(tmp_path, "x", changed_config(raw, full, key))

        def fn(w):
            return sorted(
                str(j.output[0])
                for j in w.dag.needrun_jobs()
                if j.rule.name == rule and (any_reason or w.dag.reason(j).params_changed)
            )

        return planner._run(fn, f)

    assert replanned(("materials", "ninjaflex", "youngs_modulus_MPa"), "fea_scene") == sorted(
        jobs["fea_scene"]
    )
    assert replanned(("placement", "gap_mm"), "geometry_object") == sorted(jobs["geometry_object"])
    for key in [("mesh", k) for k in ("size_mm", "min_angle_deg", "order", "arc_chord_mm")]:
        assert replanned(key, "geometry_finger") == jobs["geometry_finger"], key
    assert replanned(("render", "stress_ref_MPa"), "render_scene") == sorted(jobs["render_scene"])
    # every model; one that starts from another's weights (train.models.<m>.start_from) for
    # its new input: Snakemake checks a job's params only where nothing upstream reruns
    assert replanned(("train", "seed"), "train_model", any_reason=True) == sorted(
        jobs["train_model"]
    )
    fine_tuned = {
        f"results/train/{m}/model.pt"
        for m, e in full["train"]["models"].items()
        if e.get("start_from")
    }
    assert fine_tuned
    assert replanned(("train", "seed"), "train_model") == sorted(
        set(jobs["train_model"]) - fine_tuned
    )


# ------------------------------------------------- training on generated objects
DIVERSE = ROOT / "config" / "diverse.yaml"
DIVERSE_SLICE = ROOT / "config" / "diverse_slice.yaml"


def _train_and_diversity_jobs(planner, configfiles):
    """``({model: (params, sorted input)} of train_model, outputs of evaluate_diversity)``."""

    def fn(w):
        train = {
            j.wildcards.model: ({k: v for k, v in j.params.items()}, sorted(map(str, j.input)))
            for j in w.dag.jobs
            if j.rule.name == "train_model"
        }
        return train, sorted(
            str(f) for j in w.dag.jobs if j.rule.name == "evaluate_diversity" for f in j.output
        )

    return planner._run(fn, configfiles)


def test_diversity_comparison_is_planned_with_generated_objects_only(tmp_path):
    """config/diverse.yaml (and its slice) plans plain_paper_objects, the same job as the
    paper config's plain model apart from its name (params, input shards), and the
    comparison; the paper and smoke configs plan neither."""
    planner = Planner(tmp_path)
    models = {"plain", "occlusion", "camera"}
    paper, none = _train_and_diversity_jobs(planner, [ROOT / "config" / "config.yaml"])
    assert set(paper) == models and none == []
    smoke, none = _train_and_diversity_jobs(planner, [SMOKE])
    assert set(smoke) == models | {"pitch"} and none == []
    for files, n_blobs in (([DIVERSE, DIVERSE_SLICE], 60), ([DIVERSE], 300)):
        train, diversity = _train_and_diversity_jobs(planner, files)
        assert set(train) == models | {"plain_paper_objects"}, files
        assert train["plain_paper_objects"] == paper["plain"], files
        shards = train["plain"][1]
        blobs = [f for f in shards if f.startswith("results/dataset/shards/blob_s")]
        # each blob at the paper's 3 heights and at the training's face heights where it
        # clears the base (finray.config.face_heights)
        cfg = validate_config(
            merge_config(read_config_file(DIVERSE), {"generated": {"count": n_blobs}})
        )
        names = [n for n in cfg["objects"] if n.startswith("blob_s")]
        assert len(names) == n_blobs
        assert len(blobs) == sum(len(object_heights(cfg, n)) for n in names) > 3 * n_blobs
        assert sorted(set(shards) - set(blobs)) == paper["plain"][1]
        assert train["plain"][0] == paper["plain"][0]  # the same settings, more objects
        assert "results/evaluate/diversity/table.csv" in diversity
        assert "results/evaluate/diversity/summary.json" in diversity


def test_diversity_needs_generated_training_objects(tmp_path):
    """generated.compare_model null, or generated objects that do not train: nothing planned."""
    planner = Planner(tmp_path)
    raw = yaml.safe_load(SMOKE.read_text())
    for gen in ({"count": 2, "compare_model": None}, {"count": 2, "split": "shape"}):
        f = _write(tmp_path, "gen", {**raw, "generated": gen})
        train, diversity = _train_and_diversity_jobs(planner, [f])
        assert "plain_paper_objects" not in train and diversity == [], gen
    # (a model trained from scratch: the fine-tuned occlusion model cannot be compared)
    f = _write(tmp_path, "gen", {**raw, "generated": {"count": 2, "compare_model": "camera"}})
    train, diversity = _train_and_diversity_jobs(planner, [f])
    assert train["camera_paper_objects"][0] == train["camera"][0] and diversity


def test_extra_heights_reach_their_model_only(tmp_path):
    """extra_train_heights_mm (here camera at 17 mm over config.yaml): the camera model
    trains on every training object at 17 mm as well, the other models and the ridge
    baseline on the paper's heights only; sim-to-real's no-context fit reads the camera
    model's shards. Without the key, every model trains on the same shards."""

    def fn(w):
        jobs = {j.rule.name + ":" + j.wildcards.get("model", ""): j for j in w.dag.jobs}
        inputs = {name: sorted(map(str, j.input)) for name, j in jobs.items()}
        return inputs, sorted(map(str, jobs["sim2real_no_context:"].input.sim))

    paper = ROOT / "config" / "config.yaml"
    extra = _write(
        tmp_path, "extra", {"extends": str(paper), "extra_train_heights_mm": {"camera": [17]}}
    )
    planner = Planner(tmp_path)
    before, _ = planner._run(fn, [paper])
    inputs, no_context = planner._run(fn, [extra])
    camera, plain = inputs["train_model:camera"], inputs["train_model:plain"]
    added = sorted(set(camera) - set(plain))
    assert len(added) == 15 and all("/h17/" in f for f in added)
    assert set(plain) < set(camera) and not any("/h17/" in f for f in plain)
    assert inputs["train_model:occlusion"] == plain == before["train_model:plain"]
    assert before["train_model:camera"] == plain
    assert inputs["evaluate_baseline:"] == before["evaluate_baseline:"]
    assert no_context == [f for f in camera if f.startswith("results/dataset/shards/")]
