"""Render every frame of one FEA scene into one pixel frame: RGB PNG + stress EXR.

Output directory of :func:`render_scene` (files for the frames that
``RenderParams.files_per_scene`` selects -- a few, evenly spaced, by default (the
schema's ``render.files_per_scene``; None writes all); every frame goes in memory to
the dataset shard, see :func:`finray.dataset.render_shard`)::

    image_0000.png    camera image (H, W, 3) uint8: the finger seen at the job's pitch
    stress_0000.exr   float32 channels, always in the front (pitch 0) pixel frame:
                      ``stress``: mean of log10(1 + sigma/ref) over the pixel's material
                      where the finger covers >= half the pixel, else 0 (the stress map);
                      ``coverage``: finger fraction of each pixel;
                      ``stress_area``: area average of log10(1 + sigma/ref), background
                      0 (= stress x coverage where coverage >= 0.5; exact to downsample)
    ...
    index.json        written last: frames (index, solver frame, displacement, forces,
                      contact height (mm, NaN without contact),
                      file names, null for frames without files), the render
                      parameters, pitch, renderer, scene

At pitch 0 the image comes from the 2D rasteriser (the same pixels pyvista's
front view gives, to within anti-aliasing); at any other pitch (or with
``backend="pyvista"``) from pyvista. The stress map is a property of the finger,
not of the camera: it is always rasterised in the front view, so the stress
target of a pitched image is the front-view map of the same frame.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..logs import Progress
from .imageio import read_exr, read_png, write_exr, write_png
from .params import RenderParams
from .raster import Rasterizer, composite
from .result import FEAResult, load_fea_result, resample_frames
from ..schema import schema_default

INDEX_FILE = "index.json"
STRESS_TRANSFORM = "log10(1 + von_mises_MPa / stress_ref_MPa)"

log = logging.getLogger(__name__)


def _image_name(k: int) -> str:
    return f"image_{k:04d}.png"


def _stress_name(k: int) -> str:
    return f"stress_{k:04d}.exr"


class SceneRenderer:
    """Renders frames of one result (one rasteriser, one pyvista plotter if needed)."""

    def __init__(
        self,
        result: FEAResult,
        params: RenderParams | None = None,
        pitch_deg: float = 0.0,
        extrusion_mm: float = schema_default("finger.extrusion_mm"),
        backend: str = "auto",
        draw_object: bool = False,
    ):
        if backend not in ("auto", "raster", "pyvista"):
            raise ValueError(f"backend must be auto, raster or pyvista, not {backend!r}")
        if backend == "raster" and pitch_deg != 0:
            raise ValueError("the 2D rasteriser renders the front view (pitch 0) only")
        self.result = result
        self.params = params or RenderParams()
        self.pitch_deg = float(pitch_deg)
        self.draw_object = draw_object
        self.raster = Rasterizer(result.mesh, self.params)
        self.backend = (
            "pyvista"
            if (backend == "pyvista" or (backend == "auto" and pitch_deg != 0))
            else "raster"
        )
        self.pv = None
        if self.backend == "pyvista":
            from .pvrender import PyVistaRenderer

            self.pv = PyVistaRenderer(
                result.mesh,
                self.params,
                extrusion_mm=extrusion_mm,
                pitch_deg=pitch_deg,
                object_edges=result.object_edges if draw_object else None,
                n_object_points=result.object_points_mm.shape[1] if draw_object else 0,
            )

    def frame(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(rgb (H, W, 3) uint8, {"stress", "coverage", "stress_area"} (H, W) float32)``
        of frame k (see :meth:`Rasterizer.render`)."""
        res = self.result
        pts = res.deformed_points(k)
        coverage, stress, stress_area = self.raster.render(pts, res.von_mises_MPa[k])
        obj = res.object_points_mm[k] if self.draw_object else None
        if self.pv is not None:
            rgb = self.pv.render(pts, obj)
        else:
            ocov = self.raster.polygon_coverage(obj, res.object_edges) if obj is not None else None
            rgb = composite(coverage, self.params, ocov)
        return rgb, {"stress": stress, "coverage": coverage, "stress_area": stress_area}

    def close(self) -> None:
        if self.pv is not None:
            self.pv.close()
            self.pv = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def render_scene(
    result_npz: str | Path,
    out_dir: str | Path,
    pitch_deg: float = 0.0,
    *,
    params: RenderParams | None = None,
    extrusion_mm: float = schema_default("finger.extrusion_mm"),
    backend: str = "auto",
    draw_object: bool = False,
    scene: dict | None = None,
    on_frame: Callable[[int, np.ndarray, dict], None] | None = None,
    on_points: Callable[[int, np.ndarray], None] | None = None,
    log_every_s: float = 30.0,
) -> dict:
    """Render all frames of a solver result into ``out_dir``; returns the index.

    ``params.frames_per_scene`` frames are taken evenly in displacement (fields
    interpolated between solver frames), or the solver's frames if it is None.
    The PNG + EXR files are written for ``params.written_frames`` (``files_per_scene``;
    frame files of an earlier render in ``out_dir`` are removed first);
    ``on_frame(k, rgb, maps)``, if given, receives every frame in memory, in order
    (``rgb, maps`` as :meth:`SceneRenderer.frame` returns them); ``on_points(k, points)``,
    if given, every frame's deformed nodes (N, 2) mm (the camera views).
    ``scene`` (object, material, height_mm, split, ...) is copied into the index.
    ``draw_object`` draws the pushing object (figures only; never for training).
    A progress line (frame k/n, travel mm, elapsed s) goes to the ``finray.render``
    log at most every ``log_every_s`` seconds, and at the last frame.
    """
    params = params or RenderParams()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / INDEX_FILE).unlink(missing_ok=True)
    for stale in [*out_dir.glob("image_*.png"), *out_dir.glob("stress_*.exr")]:
        stale.unlink()
    res = resample_frames(load_fea_result(result_npz), params.frames_per_scene)
    t0 = time.perf_counter()
    frames = []
    exr_meta = {
        "stress_transform": STRESS_TRANSFORM,
        "stress_ref_MPa": params.stress_ref_MPa,
        "window_x_mm": list(params.window_x_mm),
        "window_y_mm": list(params.window_y_mm),
        "px_per_mm": params.px_per_mm,
    }
    written = np.zeros(res.n_frames, dtype=bool)
    written[params.written_frames(res.n_frames)] = True
    max_vm = res.von_mises_MPa.max(axis=1)
    with SceneRenderer(res, params, pitch_deg, extrusion_mm, backend, draw_object) as r:
        sc = scene or {}
        what = (
            f"render {sc['object']}_{sc.get('material')}_h{float(sc.get('height_mm', 0)):g}"
            if "object" in sc
            else f"render {Path(result_npz).parent}"
        )
        log.info(f"{what}: {res.n_frames} frames at pitch {pitch_deg:g} deg ({r.backend})")
        progress = Progress(log, what, res.n_frames, log_every_s)
        for k in range(res.n_frames):
            rgb, maps = r.frame(k)
            if written[k]:
                write_png(out_dir / _image_name(k), rgb)
                write_exr(out_dir / _stress_name(k), maps, dict(exr_meta, frame=k))
            if on_frame is not None:
                on_frame(k, rgb, maps)
            if on_points is not None:
                on_points(k, res.deformed_points(k))
            frames.append(
                {
                    "frame": k,
                    "fea_frame": float(res.fea_frame[k]),
                    "displacement_mm": float(res.displacement_mm[k]),
                    "fx_N": float(res.fx_N[k]),
                    "fy_N": float(res.fy_N[k]),
                    "contact_y_mm": float(res.contact_y_mm[k]),  # NaN without contact
                    "max_von_mises_MPa": float(max_vm[k]),
                    "image": _image_name(k) if written[k] else None,
                    "stress": _stress_name(k) if written[k] else None,
                }
            )
            progress(k + 1, f"travel {res.displacement_mm[k]:.2f} mm")
        backend_used = r.backend
    index = {
        "result": str(result_npz),
        "pitch_deg": float(pitch_deg),
        "renderer": backend_used,
        "draw_object": bool(draw_object),
        "extrusion_mm": float(extrusion_mm),
        "stress_transform": STRESS_TRANSFORM,
        "params": params.to_dict(),
        "scene": dict(scene or {}),
        "n_frames": res.n_frames,
        "n_files": int(written.sum()),
        "frames": frames,
        "seconds": time.perf_counter() - t0,
    }
    (out_dir / INDEX_FILE).write_text(json.dumps(index, indent=1))
    return index


def load_render_index(render_dir: str | Path) -> dict:
    """The ``index.json`` of a rendered scene."""
    return json.loads((Path(render_dir) / INDEX_FILE).read_text())


def read_render_frame(
    render_dir: str | Path, k: int, index: dict | None = None
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """``(rgb uint8 (H, W, 3), {"stress", "coverage", "stress_area"} float32 (H, W))``
    of frame k."""
    index = index or load_render_index(render_dir)
    fr = index["frames"][k]
    if fr.get("image") is None:
        written = [f["frame"] for f in index["frames"] if f.get("image") is not None]
        raise FileNotFoundError(
            f"{render_dir}: frame {k} was not written to files "
            f"(render.files_per_scene); frames with files: {written}"
        )
    rgb = read_png(Path(render_dir) / fr["image"])
    chans, _ = read_exr(Path(render_dir) / fr["stress"])
    return rgb, chans
