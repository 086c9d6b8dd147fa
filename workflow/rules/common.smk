# What every stage shares: the config (validated), the results' folders, canonical params,
# the scenes' views and shards. Each stage's own helpers are in helpers/<stage>.smk.
import copy
import os
import sys
from types import SimpleNamespace

import yaml
from snakemake.utils import update_config

from finray.config import (
    ConfigError,
    extra_train_heights,
    is_partial,
    merge_config,
    resolve_extends,
    typed_overrides,
    scenes,
    sim2real_model_name,
    validate_config,
)
from finray.dataset import pitch_object
from finray.dataset.params import SHARD_KEYS
from finray.scheduler_timers import end_timers_at_exit

# the job-rate limit's timers (the profile's span: they never fire) end with the run
end_timers_at_exit()

#: the repository root (this workflow is workflow/Snakefile, the catalog's layout)
REPO = os.path.dirname(workflow.basedir)
DEFAULT_CONFIGFILE = os.path.join(REPO, "config", "config.yaml")
# --config KEY=VALUE, typed as YAML types it (Snakemake reads a nested value's scalars
# as strings), on top of whichever config is read
_cli = typed_overrides(dict(workflow.config_settings.config or {}))
if not workflow.config_settings.configfiles:
    # no --configfile: the paper's full set-up
    config.clear()
    config.update(yaml.safe_load(open(DEFAULT_CONFIGFILE)))
elif is_partial(config):
    # a config file of changes only (no finger, no objects): on top of config.yaml
    _merged = merge_config(yaml.safe_load(open(DEFAULT_CONFIGFILE)), dict(config))
    config.clear()
    config.update(_merged)
elif "extends" in config:
    # a config file that extends another (config/diverse.yaml: config.yaml plus the
    # generated objects): that file under the given ones, the path relative to the last
    # given file that names it
    _named = [
        f
        for f in workflow.config_settings.configfiles
        if "extends" in (yaml.safe_load(open(f)) or {})
    ]
    try:
        _merged = resolve_extends(dict(config), os.path.dirname(_named[-1]))
    except ConfigError as _err:
        sys.stderr.write(f"finray: config error: {_err}\n")
        sys.exit(1)
    config.clear()
    config.update(_merged)
update_config(config, _cli)

try:
    _validated = validate_config(config, base_dir=REPO)
    try:  # the viewpoint study needs a held-out shape (or dataset.pitch_object)
        pitch_object(_validated)
    except ValueError as _exc:
        raise ConfigError("dataset.pitch_object", str(_exc).split(": ", 1)[-1]) from None
except ConfigError as _err:
    sys.stderr.write(f"finray: config error: {_err}\n")
    sys.exit(1)
config.clear()
config.update(_validated)


def script_path(name):
    """workflow/scripts/<name> from anywhere: a rule that another file reuses (``use rule
    ... with:``, studies/seeds/rules.smk) keeps its script, which a path relative to the
    rule file would not (Snakemake resolves it against the reusing file)."""
    return os.path.join(workflow.basedir, "scripts", name)


RESULTS = "results"
GEOMETRY = f"{RESULTS}/geometry"
FEA = f"{RESULTS}/fea"
RENDER = f"{RESULTS}/render"
DATASET = f"{RESULTS}/dataset"
TRAIN = f"{RESULTS}/train"
LAB = f"{RESULTS}/lab"  # the emulated lab rig
SPREAD = f"{RESULTS}/evaluate/spread"  # the spread and training-budget studies' variants


# one thread per job: the DAG runs jobs side by side (numpy/scipy/torch would
# otherwise each start a thread per core and fight for the two cores)
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


# ------------------------------------------------------------------ provenance
# Every config value a job reads is a param (or input) of that job, so that changing it
# re-plans exactly the jobs that read it. Snakemake records a param by its repr: params
# are passed in canonical form (mapping keys sorted) so that the same config with its
# keys in another order re-plans nothing (tests/workflow/test_provenance.py).


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
    return canonical(
        {k: v for k, v in sec.items() if (keys is None or k in keys) and k not in drop}
    )


wildcard_constraints:
    object="[A-Za-z0-9_-]+",
    material="[A-Za-z0-9_-]+",
    height=r"\d+(\.\d+)?",
    pitch=r"\d+(\.\d+)?",


def height_labels():
    """Contact heights as they appear in file names (mm, no trailing zeros)."""
    return [f"{h:g}" for h in config["heights_mm"]]


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


def shard_files(
    splits=None, pitch=None, exclude_objects=(), model=None, every_height=False, paper_heights=False
):
    """Shards of every rendered view (optionally of some splits, or one pitch only, less
    those of ``exclude_objects``), sorted: the order of the objects in the config does not
    change what a job reads. Of the training objects' extra heights (``extra_train_heights_mm``)
    only those of ``model``, or all where ``every_height``: what reads shards without a
    model in mind sees the paper's heights and the face heights (``face_heights_mm``).
    ``paper_heights``: the paper's heights (heights_mm) only."""
    skip = (
        set()
        if every_height
        else (
            set(extra_train_heights(config))
            - set(extra_train_heights(config, model) if model else ())
        )
    )
    paper = {float(h) for h in config["heights_mm"]}
    return sorted(
        f"{DATASET}/shards/{s.object}/{s.material}/h{s.height_mm:g}/p{pitch_label(p)}.npz"
        for s, p in rendered_views()
        if (splits is None or s.split in splits)
        and (pitch is None or p == pitch)
        and s.object not in exclude_objects
        and not (s.split == "train" and s.height_mm in skip)
        and (not paper_heights or s.height_mm in paper)
    )


def model_names():
    """Names of train.models, sorted."""
    return sorted(config["train"]["models"])


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
