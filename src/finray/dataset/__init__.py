"""Dataset stage: rendered scenes -> network shards (one ``.npz`` per scene) + manifest.

Public API:

- :func:`segment`, :func:`area_resample` -- image operations shared with real cameras
- :func:`sample_augment`, :func:`apply_augment`, :func:`augment_seed` -- seeded,
  replayable salt-and-pepper noise and disc occlusion
- :class:`DatasetParams` (config ``dataset``), :func:`build_shard`, :func:`load_shard`,
  :func:`load_frames` (the frames of shards at one size), :func:`write_manifest`,
  :func:`prepare_frame`, :class:`FramePreparer`
- :func:`render_shard` -- render a solver result and build its shard in one pass
- :func:`pitch_object`, :func:`scene_splits` -- the splits
- :func:`example_figure` -- the paper-style figure
"""

from .augment import (
    NOISE_LEVELS,
    OCCLUSION_LEVELS,
    AugmentParams,
    apply_augment,
    augment_seed,
    disc_diameters,
    sample_augment,
)
from .imageops import area_resample, segment, to_gray
from .params import DatasetParams, scene_id, size_key
from .shards import (
    FRAME_COLUMNS,
    MANIFEST_COLUMNS,
    FramePreparer,
    build_shard,
    load_frames,
    load_shard,
    prepare_frame,
    render_shard,
    write_manifest,
)
from .splits import SPLITS, pitch_object, scene_splits


def __getattr__(name: str):
    # the figure renders frames (render.scene): loaded on first use, so that a reader of
    # shards (training, evaluation, predict) does not load the renderer
    if name == "example_figure":
        from .figures import example_figure

        return example_figure
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "FRAME_COLUMNS",
    "MANIFEST_COLUMNS",
    "NOISE_LEVELS",
    "OCCLUSION_LEVELS",
    "SPLITS",
    "AugmentParams",
    "DatasetParams",
    "FramePreparer",
    "apply_augment",
    "area_resample",
    "augment_seed",
    "build_shard",
    "disc_diameters",
    "example_figure",
    "load_frames",
    "load_shard",
    "pitch_object",
    "prepare_frame",
    "render_shard",
    "sample_augment",
    "scene_id",
    "scene_splits",
    "segment",
    "size_key",
    "to_gray",
    "write_manifest",
]
