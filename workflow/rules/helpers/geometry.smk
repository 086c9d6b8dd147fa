# Helpers of the geometry rules (geometry.smk): the objects' files, shapes and splits.
from finray.config import object_is_meshed


def object_geometry_files():
    return sorted(
        expand(
            f"{GEOMETRY}/objects/{{object}}_h{{height}}.npz",
            object=list(config["objects"]),
            height=height_labels(),
        )
    )


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
