"""Dataset shards: one ``.npz`` per rendered scene (and pitch), plus a CSV manifest.

For each frame of a render directory (see :mod:`finray.render.scene`):

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

Also per frame: ``frame``, ``fea_frame``, ``displacement_mm``, ``fx_N``, ``fy_N``;
and ``meta`` (JSON): the scene (object, material, height_mm, split, splits,
pitch_deg, scene_id), sizes, crop, render and dataset parameters.

Corruptions (noise, occlusion) are not baked in: they are drawn at use time
from :func:`~finray.dataset.augment.augment_seed` so any sample can be replayed.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from ..render.params import RenderParams
from ..render.scene import load_render_index, read_render_frame
from .augment import NOISE_LEVELS, OCCLUSION_LEVELS
from .imageops import area_resample, segment

MANIFEST_COLUMNS = ["shard", "scene_id", "object", "material", "height_mm", "split", "pitch_deg",
                    "frame", "fea_frame", "displacement_mm", "fx_N", "fy_N"]


@dataclass(frozen=True)
class DatasetParams:
    """Settings of the dataset stage (config section ``dataset``)."""

    #: Output sizes (height, width); height = 2 x width.
    sizes: tuple[tuple[int, int], ...] = ((128, 64), (64, 32))
    #: Crop window in image-plane mm (2:1 like the sizes).
    crop_x_mm: tuple[float, float] = (-5.0, 35.0)
    crop_y_mm: tuple[float, float] = (0.0, 80.0)
    threshold: str | float = "isodata"
    foreground: str = "bright"
    min_object_frac: float = 1e-3
    max_hole_frac: float = 2e-4
    keep_largest: bool = True
    noise_levels: tuple[tuple[str, float], ...] = tuple(NOISE_LEVELS.items())
    occlusion_levels: tuple[tuple[str, tuple[float, float]], ...] = tuple(OCCLUSION_LEVELS.items())
    occluder_value: float = 0.0
    seed: int = 0
    pitch_object: str | None = None

    def __post_init__(self):
        for h, w in self.sizes:
            if h != 2 * w:
                raise ValueError(f"dataset.sizes: {h}x{w} is not height = 2 x width")
        cw = self.crop_x_mm[1] - self.crop_x_mm[0]
        ch = self.crop_y_mm[1] - self.crop_y_mm[0]
        if cw <= 0 or ch <= 0:
            raise ValueError("dataset.crop_x_mm / crop_y_mm: empty crop")
        if abs(ch - 2 * cw) > 1e-9:
            raise ValueError(f"dataset.crop_y_mm: the crop ({cw:g} x {ch:g} mm) must be twice "
                             "as tall as wide, like the output sizes")

    @classmethod
    def from_config(cls, section: dict | None) -> "DatasetParams":
        section = dict(section or {})
        names = {f.name for f in fields(cls)}
        kw = {}
        for k, v in section.items():
            if k not in names:
                continue
            if k == "sizes":
                v = tuple(tuple(int(x) for x in s) for s in v)
            elif k == "noise_levels":
                v = tuple((str(a), float(b)) for a, b in dict(v).items())
            elif k == "occlusion_levels":
                v = tuple((str(a), (float(b[0]), float(b[1]))) for a, b in dict(v).items())
            elif isinstance(v, list):
                v = tuple(v)
            kw[k] = v
        return cls(**kw)

    @property
    def noise(self) -> dict[str, float]:
        return dict(self.noise_levels)

    @property
    def occlusion(self) -> dict[str, tuple[float, float]]:
        return dict(self.occlusion_levels)

    def segment(self, image: np.ndarray) -> np.ndarray:
        return segment(image, self.threshold, self.foreground, self.min_object_frac,
                       self.max_hole_frac, self.keep_largest)

    def to_dict(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["sizes"] = [list(s) for s in self.sizes]
        d["noise_levels"] = self.noise
        d["occlusion_levels"] = {k: list(v) for k, v in self.occlusion.items()}
        d["crop_x_mm"], d["crop_y_mm"] = list(self.crop_x_mm), list(self.crop_y_mm)
        return d


def size_key(size: tuple[int, int]) -> str:
    return f"{size[0]}x{size[1]}"


def scene_id(scene: dict) -> str:
    """``<object>_<material>_h<height>_p<pitch>``."""
    return (f"{scene.get('object', 'unknown')}_{scene.get('material', 'unknown')}"
            f"_h{float(scene.get('height_mm', 0)):g}_p{float(scene.get('pitch_deg', 0)):g}")


def prepare_frame(rgb: np.ndarray, maps: dict[str, np.ndarray] | None, box_px,
                  params: DatasetParams) -> dict[str, np.ndarray]:
    """Network arrays of one image at every size: ``input_HxW``, ``mask_HxW`` and,
    if the render's stress maps are given (simulation: ``stress_area`` and
    ``coverage``), ``stress_HxW``. ``box_px`` is the crop in the image's pixel
    edges (``RenderParams.box_px`` for renders; a calibrated box for a camera)."""
    sil = params.segment(rgb).astype(np.float64)
    out = {}
    for size in params.sizes:
        k = size_key(size)
        soft = area_resample(sil, box_px, size)
        out[f"input_{k}"] = np.clip(np.rint(soft * 255.0), 0, 255).astype(np.uint8)
        out[f"mask_{k}"] = (soft >= 0.5).astype(np.uint8)
        if maps is not None:
            cov = area_resample(maps["coverage"], box_px, size)
            area = area_resample(maps["stress_area"], box_px, size)
            full = cov >= 0.5
            stress = np.zeros(size, dtype=np.float64)
            stress[full] = area[full] / cov[full]
            out[f"stress_{k}"] = stress.astype(np.float32)
    return out


def build_shard(render_dir: str | Path, out_npz: str | Path, scene: dict | None = None,
                params: DatasetParams | None = None) -> dict:
    """Build the shard of one rendered scene; returns its ``meta``.

    ``scene`` (object, material, height_mm, split, splits) overrides what the render
    index holds; ``pitch_deg`` always comes from the render. ``splits`` defaults to
    ``[split]`` (see :func:`~finray.dataset.splits.scene_splits`).
    """
    params = params or DatasetParams()
    index = load_render_index(render_dir)
    rparams = RenderParams.from_config(index["params"])
    sc = dict(index.get("scene") or {})
    sc.update(scene or {})
    sc["pitch_deg"] = float(index["pitch_deg"])
    if "height_mm" in sc:
        sc["height_mm"] = float(sc["height_mm"])
    sc.setdefault("split", "train")
    sc["splits"] = list(sc.get("splits") or [sc["split"]])
    sc["scene_id"] = scene_id(sc)
    box = rparams.box_px(params.crop_x_mm, params.crop_y_mm)
    arrays: dict[str, list] = {}
    for k in range(index["n_frames"]):
        rgb, maps = read_render_frame(render_dir, k, index)
        for name, arr in prepare_frame(rgb, maps, box, params).items():
            arrays.setdefault(name, []).append(arr)
    fr = index["frames"]
    meta = {
        "scene": sc, "sizes": [list(s) for s in params.sizes], "crop_box_px": list(box),
        "render_dir": str(render_dir), "render": index["params"], "renderer": index["renderer"],
        "stress_transform": index["stress_transform"], "dataset": params.to_dict(),
        "n_frames": index["n_frames"],
    }
    out = {name: np.stack(v) for name, v in arrays.items()}
    out.update(
        frame=np.array([f["frame"] for f in fr], dtype=np.int32),
        fea_frame=np.array([f["fea_frame"] for f in fr], dtype=np.float64),
        displacement_mm=np.array([f["displacement_mm"] for f in fr], dtype=np.float64),
        fx_N=np.array([f["fx_N"] for f in fr], dtype=np.float64),
        fy_N=np.array([f["fy_N"] for f in fr], dtype=np.float64),
        meta=np.array(json.dumps(meta)),
    )
    Path(out_npz).parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out_npz, **out)
    return meta


def load_shard(path: str | Path) -> dict:
    """All arrays of a shard, with ``meta`` decoded to a dict."""
    with np.load(path, allow_pickle=False) as f:
        d = {k: f[k] for k in f.files}
    d["meta"] = json.loads(str(d["meta"]))
    return d


def write_manifest(shard_paths, out_csv: str | Path, relative_to: str | Path | None = None):
    """One row per frame and split of every shard (a pitch-0 frame of the pitch object
    appears under its own split and under ``pitch``); returns the DataFrame.

    Columns: ``shard`` (path, relative to ``relative_to`` if given), scene_id, object,
    material, height_mm, split, pitch_deg, frame, fea_frame, displacement_mm, fx_N, fy_N.
    """
    import pandas as pd

    rows = []
    for p in sorted(str(s) for s in shard_paths):
        with np.load(p, allow_pickle=False) as f:
            meta = json.loads(str(f["meta"]))
            per_frame = {k: f[k] for k in ("frame", "fea_frame", "displacement_mm", "fx_N", "fy_N")}
        sc = meta["scene"]
        name = str(Path(p).resolve().relative_to(Path(relative_to).resolve())) if relative_to else p
        for split in sc["splits"]:
            for i in range(len(per_frame["frame"])):
                rows.append({
                    "shard": name, "scene_id": sc["scene_id"], "object": sc.get("object"),
                    "material": sc.get("material"), "height_mm": sc.get("height_mm"),
                    "split": split, "pitch_deg": sc["pitch_deg"],
                    **{k: v[i].item() for k, v in per_frame.items()}})
    df = pd.DataFrame(rows, columns=MANIFEST_COLUMNS)
    Path(out_csv).parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out_csv, index=False)
    return df
