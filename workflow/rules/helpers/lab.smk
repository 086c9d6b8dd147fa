# Helpers of the emulated lab rig's rules (lab.smk): its takes, as-built finger and objects.


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


def lab_take_seed(wildcards, seed=None):
    """The take's seed: lab.seed (or ``seed``) and its name (adding a take leaves the
    others alone)."""
    seed = config["lab"]["seed"] if seed is None else seed
    return seed + zlib.crc32(f"{wildcards.object}_h{wildcards.height}".encode()) % 100000


# ---- the drawn rigs (lab.rigs; rigs.smk): each a whole lab section of its own


def rig_names():
    """The drawn rigs: rig1 .. rig<lab.rigs.count>."""
    return _rig_names(config["lab"]["rigs"])


def rig_lab(rig):
    """Rig ``rig``'s lab section (finray.lab.rigs.draw_rig)."""
    return draw_rig(config["lab"], rig_index(rig))


def rig_takes(rig):
    """Rig ``rig``'s takes: <object>_h<height>, as lab_takes."""
    lab = rig_lab(rig)
    return [f"{o}_h{h:g}" for o in sorted(lab["objects"]) for h in lab["heights_mm"]]


def rig_polygon_input(wildcards):
    spec = rig_lab(wildcards.rig)["objects"][wildcards.object]
    return [spec["path"]] if spec["type"] == "polygon_file" else []


def rig_take_seed(wildcards):
    """As lab_take_seed, from the rig's own lab.seed."""
    return lab_take_seed(wildcards, rig_lab(wildcards.rig)["seed"])
