# Config validation and target lists. Stage rules use these helpers only.
import sys

import yaml
from snakemake.utils import update_config

from finray.config import ConfigError, object_is_meshed, scenes, validate_config

DEFAULT_CONFIGFILE = "config/config.yaml"
if not workflow.config_settings.configfiles:
    # no --configfile: the paper's full set-up, with any --config KEY=VALUE on top
    _overrides = dict(config)
    config.clear()
    config.update(yaml.safe_load(open(DEFAULT_CONFIGFILE)))
    update_config(config, _overrides)

try:
    _validated = validate_config(config, base_dir=workflow.basedir)
except ConfigError as _err:
    sys.stderr.write(f"finray: config error: {_err}\n")
    sys.exit(1)
config.clear()
config.update(_validated)

RESULTS = "results"
GEOMETRY = f"{RESULTS}/geometry"


wildcard_constraints:
    object="[A-Za-z0-9_-]+",
    height=r"\d+(\.\d+)?",


def height_labels():
    """Contact heights as they appear in file names (mm, no trailing zeros)."""
    return [f"{h:g}" for h in config["heights_mm"]]


def object_geometry_files():
    return expand(
        f"{GEOMETRY}/objects/{{object}}_h{{height}}.npz",
        object=list(config["objects"]),
        height=height_labels(),
    )


def polygon_file_input(wildcards):
    """The user's polygon file, so that editing it re-places the object."""
    spec = config["objects"][wildcards.object]
    return [spec["path"]] if spec["type"] == "polygon_file" else []


def object_spec(wildcards):
    return config["objects"][wildcards.object]


def object_deformable(wildcards):
    """Objects simulated in any deformable material get a mesh; rigid ones do not."""
    return object_is_meshed(config, wildcards.object)


def all_targets():
    return [f"{GEOMETRY}/gallery.pdf", f"{GEOMETRY}/finger_surface.ply"] + object_geometry_files()
