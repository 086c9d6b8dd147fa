# Helpers of the emulated lab rig's rules (lab.smk): its takes, as-built finger and objects.
import functools
import zlib

from finray.emulator.as_built import (
    as_built_fea,
    as_built_finger,
    as_built_material,
    as_built_print_law,
)
from finray.emulator.rigs import (
    draw_rig,
    rig_index,
    rig_names as _rig_names,
    selection_rig_names as _selection,
)


def lab_takes(lab=None):
    """Every take's name: <object>_h<height> (of ``lab``, a lab section; the config's)."""
    lab = config["lab"] if lab is None else lab
    return [f"{o}_h{h:g}" for o in sorted(lab["objects"]) for h in lab["heights_mm"]]


def lab_finger(lab=None):
    """The as-built finger of ``lab`` (the config's lab section by default)."""
    lab = config["lab"] if lab is None else lab
    return canonical(as_built_finger(config["finger"], lab["as_built"]))


def lab_object_spec(wildcards):
    return canonical(config["lab"]["objects"][wildcards.object])


def lab_polygon_input(wildcards):
    lab = rig_lab(wildcards.rig) if "rig" in wildcards.keys() else config["lab"]
    spec = lab["objects"][wildcards.object]
    return [spec["path"]] if spec["type"] == "polygon_file" else []


def lab_take_seed(wildcards, seed=None):
    """The take's seed: lab.seed (or ``seed``) and its name (adding a take leaves the
    others alone)."""
    seed = config["lab"]["seed"] if seed is None else seed
    return seed + zlib.crc32(f"{wildcards.object}_h{wildcards.height}".encode()) % 100000


# ---- the drawn rigs (lab.rigs; rigs.smk): each a whole lab section of its own


def rig_names():
    """The drawn rigs reported: rig1 .. rig<lab.rigs.count>."""
    return _rig_names(config["lab"]["rigs"])


def selection_rig_names():
    """The drawn rigs settings are chosen on: after the reported ones (lab.rigs.selection)."""
    return _selection(config["lab"]["rigs"])


@functools.lru_cache(maxsize=None)
def rig_lab(rig):
    """Rig ``rig``'s lab section (finray.emulator.rigs.draw_rig), drawn once per planning: the
    config does not change while Snakemake plans. Read-only."""
    return draw_rig(config["lab"], rig_index(rig))


def rig_take_seed(wildcards):
    """As lab_take_seed, from the rig's own lab.seed."""
    return lab_take_seed(wildcards, rig_lab(wildcards.rig)["seed"])
