"""Force (N) and stress map from one camera frame: the API a control loop calls.

    from finray.predict import Predictor
    predict = Predictor("results/train/plain/model.ts")
    force_N, stress_log = predict(frame)        # frame: (H, W, 3) uint8 numpy array

Preprocessing is the dataset stage's: segment the finger (threshold + morphology),
crop, area-resample to the network's input. The crop is anchored on the finger
itself, so any image size and position works: the lowest row of the mask is the
clamped base, its width is the finger's base width (``base_width_mm``), which fixes
the scale (px/mm); the window ``crop_x_mm`` x ``crop_y_mm`` of the training data is
then cut around it.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch

from .dataset.imageops import area_resample, segment


class Predictor:
    """Load an exported model (``model.ts`` + ``model.ts.json``) once; call per frame."""

    def __init__(self, model_path: str | Path, threads: int = 1):
        model_path = Path(model_path)
        meta_path = Path(str(model_path) + ".json")
        if not model_path.is_file():
            raise FileNotFoundError(f"no model at {model_path}")
        if not meta_path.is_file():
            raise FileNotFoundError(f"{meta_path} (the model's preprocessing settings) is missing")
        torch.set_num_threads(threads)
        self.model = torch.jit.load(str(model_path), map_location="cpu").eval()
        self.meta = json.loads(meta_path.read_text())
        self.size = (self.meta["height"], self.meta["width"])
        pre = self.meta.get("preprocess", {})
        self.base_width_mm = pre.get("base_width_mm", 30.0)
        self.crop_x_mm = tuple(pre.get("crop_x_mm", (-5.0, 35.0)))
        self.crop_y_mm = tuple(pre.get("crop_y_mm", (0.0, 80.0)))
        self.segment_kw = pre.get("segment", {})

    def crop_box(self, mask: np.ndarray) -> tuple[float, float, float, float]:
        """Training window in pixel edges ``(col0, row0, col1, row1)`` from the mask."""
        rows = np.flatnonzero(mask.any(axis=1))
        if len(rows) == 0:
            raise ValueError("no finger found in the image (empty segmentation)")
        bottom = rows[-1]
        cols = np.flatnonzero(mask[bottom])
        left, right = cols[0], cols[-1] + 1  # pixel edges of the base
        ppm = (right - left) / self.base_width_mm
        base_edge = bottom + 1
        return (left + self.crop_x_mm[0] * ppm, base_edge - self.crop_y_mm[1] * ppm,
                left + self.crop_x_mm[1] * ppm, base_edge - self.crop_y_mm[0] * ppm)

    def preprocess(self, frame: np.ndarray) -> tuple[torch.Tensor, np.ndarray]:
        """Network input (1, 1, H, W) in [0, 1] and the full-resolution mask."""
        frame = np.asarray(frame)
        if frame.ndim not in (2, 3):
            raise ValueError(f"expected an (H, W) or (H, W, 3) image, got shape {frame.shape}")
        mask = segment(frame, **self.segment_kw)
        soft = area_resample(mask.astype(np.float64), self.crop_box(mask), self.size)
        # the training input is the 8-bit soft silhouette
        x = np.rint(np.clip(soft, 0, 1) * 255.0).astype(np.float32) / 255.0
        return torch.from_numpy(x)[None, None], mask

    @torch.no_grad()
    def __call__(self, frame: np.ndarray) -> tuple[float, np.ndarray]:
        """Force (N, along the push) and the log-stress map (H, W) of one frame."""
        x, _ = self.preprocess(frame)
        stress, force = self.model(x)
        return float(force[0, 0]), stress[0, 0].numpy()


def read_frames(path: str | Path):
    """Yield ``(name, frame)`` from an image, a folder of images or a video file."""
    import imageio.v3 as iio

    path = Path(path)
    if path.is_dir():
        files = sorted(p for p in path.iterdir()
                       if p.suffix.lower() in (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"))
        if not files:
            raise ValueError(f"no images in {path}")
        for p in files:
            yield p.name, iio.imread(p)
    elif path.suffix.lower() in (".mp4", ".avi", ".mov", ".mkv", ".webm"):
        try:
            for k, frame in enumerate(iio.imiter(path)):
                yield f"{path.stem}_{k:05d}", frame
        except Exception as exc:  # imageio has no video plugin without pyav/imageio-ffmpeg
            raise RuntimeError(f"cannot read video {path} ({exc}); install 'av' or extract "
                               "the frames to a folder") from exc
    elif path.is_file():
        yield path.name, iio.imread(path)
    else:
        raise FileNotFoundError(f"{path} does not exist")


def predict_files(model_path, source, out_dir, threads: int = 1) -> list[dict]:
    """Predict every frame of ``source``; write ``forces.csv`` and, per frame, the
    stress map as EXR and as a coloured PNG into ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import cm

    from .render.imageio import write_exr, write_png

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    p = Predictor(model_path, threads)
    rows = []
    for name, frame in read_frames(source):
        force, stress = p(frame)
        stem = Path(name).stem
        write_exr(out_dir / f"{stem}_stress.exr", {"stress": stress.astype(np.float32)},
                  {"source": str(name), "force_N": force})
        s = np.clip(stress / max(float(stress.max()), 1e-6), 0, 1)
        write_png(out_dir / f"{stem}_stress.png", (cm.inferno(s)[..., :3] * 255).astype(np.uint8))
        rows.append({"frame": name, "fx_N": force})
    with open(out_dir / "forces.csv", "w") as f:
        f.write("frame,fx_N\n")
        f.writelines(f"{r['frame']},{r['fx_N']:.6g}\n" for r in rows)
    return rows
