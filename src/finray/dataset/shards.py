"""Dataset shards: one ``.npz`` per rendered scene (and pitch), plus a CSV manifest.

For each frame of a rendered scene (see :mod:`finray.render.scene`) -- in memory
as the renderer produces it (:func:`render_shard`, the workflow) or read back from
a render directory's files (:func:`build_shard`):

1. segment the camera image (:func:`~finray.dataset.imageops.segment`; never the mesh),
2. crop the fixed window ``crop_x_mm x crop_y_mm`` (image-plane mm, the same for
   every scene and pitch) and area-average to each size ``(H, W)`` (H = 2 W):

   - ``input_HxW`` uint8 (F, H, W): the segmented silhouette area-averaged, x255 --
     the network input (a soft mask: ribs thinner than a pixel stay visible);
   - ``mask_HxW`` uint8 (F, H, W): 1 where the silhouette covers >= half the pixel;
   - ``stress_HxW`` float32 (F, H, W): the stress map at that size -- mean of
     ``log10(1 + sigma / ref)`` over the material in the pixel where the finger
     covers at least half the pixel, 0 elsewhere (exactly: area average of the
     render's ``stress_area`` over area average of its ``coverage``). It comes
     from the simulation's front view (also for pitched images); at pitch 0 its
     support agrees with ``mask_HxW``.

Also per frame: ``frame``, ``fea_frame``, ``displacement_mm``, ``fx_N``, ``fy_N``,
``contact_y_mm`` (the height of the contact's force-weighted centroid in the finger's
frame, the clamped base at 0; NaN without contact, and in shards of results without it);
and ``meta`` (JSON): the scene (object, material, height_mm, split, splits,
pitch_deg, scene_id), sizes, crop, render and dataset parameters, and
``support_iou_min``: the lowest IoU over the frames of the segmented image and the
stress support at render resolution (pixel alignment, >= 0.98 at pitch 0).

A lab recording's shard (:func:`finray.recording.ingest`) has the same ``input_HxW``,
``mask_HxW`` and per-frame values (``fx_N``: the sensor's push force; ``fea_frame``,
``displacement_mm``, ``fy_N``: NaN; also ``t_s`` and ``crop_box_px``) but no stress
map: ``meta["has_stress"]`` is false and :func:`load_shard` fills ``stress_HxW`` with NaN
(and ``contact_y_mm``, which it has not, with NaN too).

Corruptions (noise, occlusion) are not baked in: they are drawn at use time
from :func:`~finray.dataset.augment.augment_seed` so any sample can be replayed.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..render.camera_views import VIEW_COLUMNS
from ..render.params import RenderParams
from .imageops import _axis_weights
from .params import SHARD_KEYS, DatasetParams, scene_id, size_key
from ..schema import schema_default

MANIFEST_COLUMNS = [
    "shard",
    "scene_id",
    "object",
    "material",
    "height_mm",
    "split",
    "pitch_deg",
    "frame",
    "fea_frame",
    "displacement_mm",
    "fx_N",
    "fy_N",
    "contact_y_mm",
]


#: "Covers at least half the pixel", robust to rounding: area averages of binary
#: or 1/n-quantised coverage hit exactly 0.5 often, and the rounding of the sums
#: must not decide on which side they fall.
HALF = 0.5 - 1e-9


def _band(weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A dense (n_dst, n_src) resampling matrix as bands: source indices (n_dst, B)
    and weights (n_dst, B) of each row's nonzero run (padded with weight 0)."""
    nz = weights > 0
    lo = np.where(nz.any(axis=1), nz.argmax(axis=1), 0)
    hi = np.where(nz.any(axis=1), weights.shape[1] - nz[:, ::-1].argmax(axis=1), 0)
    b = max(int((hi - lo).max()), 1)
    idx = np.minimum(lo[:, None] + np.arange(b)[None, :], weights.shape[1] - 1)
    w = np.take_along_axis(weights, idx, axis=1) * (np.arange(b)[None, :] < (hi - lo)[:, None])
    return idx, w


def _apply_band(img: np.ndarray, by, bx) -> np.ndarray:
    """``wy @ img @ wx.T`` of (H, W) img for banded wy, wx (see :func:`_band`)."""
    iy, wy = by
    ix, wx = bx
    rows = np.einsum("hb,hbw->hw", wy, img[iy])  # (h, W)
    return np.einsum("hwb,wb->hw", rows[:, ix], wx)  # (h, w)


class FramePreparer:
    """The dataset arrays of images of one shape and one crop box (one per scene):
    :func:`~finray.dataset.imageops.area_resample`'s weights are computed once, as
    bands (each output pixel covers at most a few source rows and columns), so a
    frame costs a few multiply-adds per output pixel instead of dense products.

    ``prepare(rgb, maps)`` returns what :func:`prepare_frame` does; ``add(rgb,
    maps)`` keeps it, ``stacked()`` returns the kept frames as (F, H, W) arrays.
    ``support_iou`` holds, per added frame with maps, the IoU of the segmented
    image and the stress map's support (coverage >= 1/2) at render resolution:
    the pixel alignment of image and stress, checked on every frame (>= 0.98 at
    pitch 0; pitched images are not aligned with the front-view stress by design).
    """

    def __init__(self, image_shape: tuple[int, int], box_px, params: DatasetParams):
        c0, r0, c1, r1 = box_px
        if not (c1 > c0 and r1 > r0):
            raise ValueError(f"empty crop box {box_px}")
        self.image_shape = tuple(image_shape[:2])
        self.box_px = tuple(box_px)
        self.params = params
        # (key, rows band, columns band) per output size
        self._weights = [
            (
                size_key(size),
                _band(_axis_weights(self.image_shape[0], r0, r1, size[0])),
                _band(_axis_weights(self.image_shape[1], c0, c1, size[1])),
            )
            for size in params.sizes
        ]
        self._frames: dict[str, list] = {}
        self.support_iou: list[float] = []
        self._last_iou = None

    def prepare(
        self, rgb: np.ndarray, maps: dict[str, np.ndarray] | None = None
    ) -> dict[str, np.ndarray]:
        if tuple(rgb.shape[:2]) != self.image_shape:
            raise ValueError(f"image shape {rgb.shape[:2]} != {self.image_shape}")
        seg = self.params.segment(rgb)
        sil = seg.astype(np.float64)
        if maps is not None:
            support = maps["coverage"] >= 0.5
            self._last_iou = float((seg & support).sum() / max(int((seg | support).sum()), 1))
        if maps is not None:
            cov_img = np.asarray(maps["coverage"], dtype=np.float64)
            area_img = np.asarray(maps["stress_area"], dtype=np.float64)
        out = {}
        for k, by, bx in self._weights:
            soft = _apply_band(sil, by, bx)
            out[f"input_{k}"] = np.clip(np.rint(soft * 255.0), 0, 255).astype(np.uint8)
            out[f"mask_{k}"] = (soft >= HALF).astype(np.uint8)
            if maps is not None:
                cov = _apply_band(cov_img, by, bx)
                area = _apply_band(area_img, by, bx)
                full = cov >= HALF
                stress = np.zeros(cov.shape, dtype=np.float64)
                stress[full] = area[full] / cov[full]
                out[f"stress_{k}"] = stress.astype(np.float32)
        return out

    def add(self, rgb: np.ndarray, maps: dict[str, np.ndarray] | None = None) -> None:
        for name, arr in self.prepare(rgb, maps).items():
            self._frames.setdefault(name, []).append(arr)
        if maps is not None:
            self.support_iou.append(self._last_iou)

    def stacked(self) -> dict[str, np.ndarray]:
        return {name: np.stack(v) for name, v in self._frames.items()}


def prepare_frame(
    rgb: np.ndarray, maps: dict[str, np.ndarray] | None, box_px, params: DatasetParams
) -> dict[str, np.ndarray]:
    """Network arrays of one image at every size: ``input_HxW``, ``mask_HxW`` and,
    if the render's stress maps are given (simulation: ``stress_area`` and
    ``coverage``), ``stress_HxW``. ``box_px`` is the crop in the image's pixel
    edges (``RenderParams.box_px`` for renders; a calibrated box for a camera).
    (For many frames of one shape, :class:`FramePreparer` reuses the weights.)"""
    return FramePreparer(rgb.shape[:2], box_px, params).prepare(rgb, maps)


def _scene_of(index: dict, scene: dict | None) -> dict:
    sc = dict(index.get("scene") or {})
    sc.update(scene or {})
    sc["pitch_deg"] = float(index["pitch_deg"])
    if "height_mm" in sc:
        sc["height_mm"] = float(sc["height_mm"])
    sc.setdefault("split", "train")
    sc["splits"] = list(sc.get("splits") or [sc["split"]])
    sc["scene_id"] = scene_id(sc)
    return sc


def _write_shard(
    out_npz,
    index: dict,
    prep: FramePreparer,
    scene: dict | None,
    params: DatasetParams,
    box,
    render_dir,
    extra: dict | None = None,
) -> dict:
    """Save the stacked frame arrays with the per-frame values and ``meta``; returns meta.
    ``meta["support_iou_min"]``: the lowest :attr:`FramePreparer.support_iou`.
    ``extra``: ``{"arrays": ..., "meta": ...}`` added to both (the camera views)."""
    fr = index["frames"]
    meta = {
        "scene": _scene_of(index, scene),
        "sizes": [list(s) for s in params.sizes],
        "crop_box_px": list(box),
        "render_dir": str(render_dir),
        "render": index["params"],
        "renderer": index["renderer"],
        "stress_transform": index["stress_transform"],
        "dataset": {k: v for k, v in params.to_dict().items() if k in SHARD_KEYS},
        "n_frames": index["n_frames"],
        "support_iou_min": min(prep.support_iou) if prep.support_iou else None,
        **((extra or {}).get("meta") or {}),
    }
    arrays = prep.stacked()
    out = dict(arrays)
    out.update((extra or {}).get("arrays") or {})
    out.update(
        frame=np.array([f["frame"] for f in fr], dtype=np.int32),
        fea_frame=np.array([f["fea_frame"] for f in fr], dtype=np.float64),
        displacement_mm=np.array([f["displacement_mm"] for f in fr], dtype=np.float64),
        fx_N=np.array([f["fx_N"] for f in fr], dtype=np.float64),
        fy_N=np.array([f["fy_N"] for f in fr], dtype=np.float64),
        contact_y_mm=np.array([f.get("contact_y_mm", np.nan) for f in fr], dtype=np.float64),
        meta=np.array(json.dumps(meta)),
    )
    save_npz(out_npz, out)
    return meta


def save_npz(path: str | Path, arrays: dict[str, np.ndarray], level: int = 1) -> None:
    """``np.savez_compressed`` at zlib level ``level`` (1: twice as fast as numpy's
    default, files ~15 % larger); read with ``np.load`` as usual."""
    import zipfile

    from numpy.lib import format as npformat

    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=level) as zf:
        for name, arr in arrays.items():
            with zf.open(f"{name}.npy", "w", force_zip64=True) as f:
                npformat.write_array(f, np.asanyarray(arr), allow_pickle=False)


def build_shard(
    render_dir: str | Path,
    out_npz: str | Path,
    scene: dict | None = None,
    params: DatasetParams | None = None,
) -> dict:
    """Build the shard of one rendered scene from its files; returns its ``meta``.

    Every frame of the render directory must have its files (``files_per_scene``
    None). ``scene`` (object, material, height_mm, split, splits) overrides what the
    render index holds; ``pitch_deg`` always comes from the render. ``splits``
    defaults to ``[split]`` (see :func:`~finray.dataset.splits.scene_splits`).
    """
    from ..render.scene import load_render_index, read_render_frame  # the writer's only

    params = params or DatasetParams()
    index = load_render_index(render_dir)
    rparams = RenderParams.from_config(index["params"])
    box = rparams.box_px(params.crop_x_mm, params.crop_y_mm)
    prep = FramePreparer(rparams.shape, box, params)
    for k in range(index["n_frames"]):
        prep.add(*read_render_frame(render_dir, k, index))
    return _write_shard(out_npz, index, prep, scene, params, box, render_dir)


def render_shard(
    result_npz: str | Path,
    render_dir: str | Path,
    out_npz: str | Path,
    pitch_deg: float = 0.0,
    *,
    render_params: RenderParams | None = None,
    params: DatasetParams | None = None,
    extrusion_mm: float = schema_default("finger.extrusion_mm"),
    scene: dict | None = None,
    camera_views=None,
    base_width_mm: float = schema_default("finger.base_width_mm"),
) -> dict:
    """Render a solver result and build its shard in one pass; returns the shard's ``meta``.

    Each frame goes from the renderer straight to :class:`FramePreparer` (the same
    segmentation of the camera image as :func:`build_shard`, without the round
    trip through PNG + EXR files); ``render_dir`` receives ``index.json`` and the
    files of the ``render_params.files_per_scene`` frames (figures, inspection).
    The shard equals ``build_shard`` of a render with every frame's files.

    ``camera_views`` (:class:`~finray.render.camera_views.CameraViews`): each frame is
    also seen by its randomised camera, and the shard gets ``camera_input_HxW`` and
    ``camera_view`` (:mod:`finray.dataset.camera_views`; ``base_width_mm`` anchors
    their crop).
    """
    from ..render.scene import render_scene  # the renderer: the writer's only

    render_params = render_params or RenderParams()
    params = params or DatasetParams()
    box = render_params.box_px(params.crop_x_mm, params.crop_y_mm)
    prep = FramePreparer(render_params.shape, box, params)
    cams = None
    if camera_views is not None:
        from ..render import load_fea_result
        from .camera_views import CameraViewPreparer

        sid = scene_id({**(scene or {}), "pitch_deg": float(pitch_deg)})
        cams = CameraViewPreparer(
            load_fea_result(result_npz).mesh,
            extrusion_mm,
            camera_views,
            params,
            params.window(base_width_mm),
            sid,
            render_params,
        )
    index = render_scene(
        result_npz,
        render_dir,
        pitch_deg,
        params=render_params,
        extrusion_mm=extrusion_mm,
        scene=scene,
        on_frame=lambda k, rgb, maps: prep.add(rgb, maps),
        on_points=cams.add if cams is not None else None,
    )
    extra = None
    if cams is not None:
        extra = {
            "arrays": cams.stacked(),
            "meta": {
                "camera_views": camera_views.to_dict(),
                "camera_view_columns": list(VIEW_COLUMNS),
            },
        }
    return _write_shard(out_npz, index, prep, scene, params, box, render_dir, extra)


def load_shard(path: str | Path) -> dict:
    """All arrays of a shard, with ``meta`` decoded to a dict, and ``has_stress``.

    A shard without stress maps (a lab recording, :mod:`finray.recording`:
    ``meta["has_stress"]`` false) gets ``stress_HxW`` arrays of NaN, so that its
    frames stack with simulated ones and any stress metric on them is NaN, never a
    made-up number; training refuses them (:func:`finray.train.load_split`)."""
    with np.load(path, allow_pickle=False) as f:
        d = {k: f[k] for k in f.files}
    d["meta"] = json.loads(str(d["meta"]))
    d["has_stress"] = bool(d["meta"].get("has_stress", True))
    d.setdefault("contact_y_mm", np.full(len(d["frame"]), np.nan))  # shards before it, recordings
    if not d["has_stress"]:
        for name in [k for k in d if k.startswith("input_")]:
            d["stress_" + name[len("input_") :]] = np.full(d[name].shape, np.nan, np.float32)
    return d


#: The per-frame table of :func:`load_frames`.
FRAME_COLUMNS = [
    "scene_id",
    "object",
    "material",
    "height_mm",
    "pitch_deg",
    "frame",
    "displacement_mm",
    "fx_N",
    "fy_N",
    "contact_y_mm",
]


def load_frames(
    shard_paths,
    size: tuple[int, int],
    every: int = 1,
    require_stress: bool = False,
    camera: bool = False,
):
    """The frames of shards at one input size, in the order given: arrays and a
    per-frame table (the one shard reader of training, evaluation and the studies).

    Arrays, as stored: ``images`` (N, H, W) uint8 (the soft silhouette x255),
    ``stress`` (N, H, W) float32 log-stress, ``mask`` (N, H, W) bool, ``fx_N`` and
    ``fy_N`` (N,) in N (along the push and across it; NaN where a recording has none),
    ``contact_y_mm`` (N,) the contact height in mm (NaN without contact, in a recording
    and in shards built before it).
    Table (pandas): :data:`FRAME_COLUMNS`. ``every``: keep every ``every``-th frame of
    each shard (evenly over the push). Only the arrays of ``size`` are read. A shard
    without a stress map (a lab recording) gives NaN stress, or a ``ValueError`` with
    ``require_stress``. ``camera``: also ``camera_images`` (N, H, W) uint8, each frame
    seen by its randomised camera (shards rendered with camera views; ValueError else)."""
    import pandas as pd

    k = size_key(size)
    sel = slice(0, None, max(1, int(every)))
    arrays: dict[str, list] = {
        "images": [],
        "stress": [],
        "mask": [],
        "fx_N": [],
        "fy_N": [],
        "contact_y_mm": [],
    }
    rows = []
    for path in shard_paths:
        with np.load(path, allow_pickle=False) as f:
            meta = json.loads(str(f["meta"]))
            sc = meta["scene"]
            x = f[f"input_{k}"][sel]
            arrays["images"].append(x)
            if camera:
                if f"camera_input_{k}" not in f.files:
                    raise ValueError(
                        f"{path} has no camera views (render.camera_views is off for its scene)"
                    )
                arrays.setdefault("camera_images", []).append(f[f"camera_input_{k}"][sel])
            if meta.get("has_stress", True):
                arrays["stress"].append(f[f"stress_{k}"][sel])
            elif require_stress:
                raise ValueError(
                    f"{path} has no stress map (a lab recording): it cannot be "
                    "trained on by the stress + force loss"
                )
            else:
                arrays["stress"].append(np.full(x.shape, np.nan, np.float32))
            arrays["mask"].append(f[f"mask_{k}"][sel].astype(bool))
            arrays["fx_N"].append(f["fx_N"][sel])
            arrays["fy_N"].append(f["fy_N"][sel])
            arrays["contact_y_mm"].append(
                f["contact_y_mm"][sel] if "contact_y_mm" in f.files else np.full(len(x), np.nan)
            )
            frame, disp = f["frame"][sel], f["displacement_mm"][sel]
        rows.append(
            pd.DataFrame(
                {
                    "scene_id": sc["scene_id"],
                    "object": sc.get("object"),
                    "material": sc.get("material"),
                    "height_mm": float(sc.get("height_mm", np.nan)),
                    "pitch_deg": float(sc["pitch_deg"]),
                    "frame": frame,
                    "displacement_mm": disp,
                    "fx_N": arrays["fx_N"][-1],
                    "fy_N": arrays["fy_N"][-1],
                    "contact_y_mm": arrays["contact_y_mm"][-1],
                },
                columns=FRAME_COLUMNS,
            )
        )
    if not rows:
        raise ValueError("no shards given")
    return ({n: np.concatenate(v) for n, v in arrays.items()}, pd.concat(rows, ignore_index=True))


def write_manifest(shard_paths, out_csv: str | Path, relative_to: str | Path | None = None):
    """One row per frame and split of every shard (a pitch-0 frame of the pitch object
    appears under its own split and under ``pitch``); returns the DataFrame.

    Columns: ``shard`` (path, relative to ``relative_to`` if given), scene_id, object,
    material, height_mm, split, pitch_deg, frame, fea_frame, displacement_mm, fx_N, fy_N,
    contact_y_mm.
    """
    import pandas as pd

    rows = []
    for p in sorted(str(s) for s in shard_paths):
        with np.load(p, allow_pickle=False) as f:
            meta = json.loads(str(f["meta"]))
            per_frame = {k: f[k] for k in ("frame", "fea_frame", "displacement_mm", "fx_N", "fy_N")}
            n = len(per_frame["frame"])
            per_frame["contact_y_mm"] = (
                f["contact_y_mm"] if "contact_y_mm" in f.files else np.full(n, np.nan)
            )
        sc = meta["scene"]
        name = str(Path(p).resolve().relative_to(Path(relative_to).resolve())) if relative_to else p
        for split in sc["splits"]:
            for i in range(len(per_frame["frame"])):
                rows.append(
                    {
                        "shard": name,
                        "scene_id": sc["scene_id"],
                        "object": sc.get("object"),
                        "material": sc.get("material"),
                        "height_mm": sc.get("height_mm"),
                        "split": split,
                        "pitch_deg": sc["pitch_deg"],
                        **{k: v[i].item() for k, v in per_frame.items()},
                    }
                )
    df = pd.DataFrame(rows, columns=MANIFEST_COLUMNS)
    Path(out_csv).parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out_csv, index=False)
    return df
