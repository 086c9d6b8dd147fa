# Helpers of the render rules (render.smk): the renderer's settings, the pitch series, each scene's
# description and camera views.
from dataclasses import fields

from finray.dataset import scene_splits
from finray.render import RenderParams


def render_params():
    """The render section as the renderer reads it (``pitches_deg`` only picks the views)."""
    return section("render", keys={f.name for f in fields(RenderParams)})


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
    return canonical(
        {
            "object": wildcards.object,
            "material": wildcards.material,
            "height_mm": float(wildcards.height),
            "split": config["objects"][wildcards.object]["split"],
        }
    )


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
