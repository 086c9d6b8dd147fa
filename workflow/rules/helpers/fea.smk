# Helpers of the FEA rules (fea.smk, fea_benchmarks.smk): materials, the finger, the scenes' files.


def material_constants(name):
    """What the solver reads of a material (its ``source`` is documentation only)."""
    return canonical({k: v for k, v in config["materials"][name].items() if k != "source"})


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
