"""Test frames of the viewpoint experiment: pyvista perspective renders of a scene.

Independent of the training views' raster (:mod:`finray.render.perspective`): VTK's
OpenGL pipeline (depth test, headlight shading) renders the extruded finger through a
fixed pinhole camera at every pitch and distance, full frames as a camera would give
them, written as PNG for :class:`~finray.predict.Predictor`. The frames are a subset of
the scene's resampled frames (``render.frames_per_scene``), so each one's stress
target is the same frame's front-view map in the scene's dataset shard.

Output directory::

    d<distance>_p<pitch>_<frame>.png   RGB (H, W, 3) uint8
    index.json                         written last: scene, camera settings, and per
                                       image its distance, pitch, frame, FEA forces
"""

from __future__ import annotations

import json
import logging
import time
from pathlib import Path

import numpy as np

from ..logs import Progress
from .camera import PinholeCamera
from .imageio import write_png
from .params import RenderParams
from .result import load_fea_result, resample_frames
from ..schema import schema_default

log = logging.getLogger(__name__)


def viewpoint_camera(view: dict, pitch_deg: float, distance_mm: float) -> PinholeCamera:
    """The test camera (config ``evaluate.viewpoint``) at one pitch and distance:
    ``size_px`` [width, height] portrait, ``hfov_deg`` of the landscape stream (spans
    the height), ``yaw_deg``, ``roll_deg``, ``principal_offset_px``, aimed at ``target_mm``."""
    w, h = (int(v) for v in view["size_px"])
    tan_h = np.tan(np.radians(0.5 * float(view["hfov_deg"])))
    hfov_portrait = 2 * np.degrees(np.arctan(w / h * tan_h))
    tx, ty = view["target_mm"]
    return PinholeCamera.looking_at(
        (tx, ty, 0.0),
        width=w,
        height=h,
        hfov_deg=hfov_portrait,
        distance_mm=float(distance_mm),
        yaw_deg=float(view["yaw_deg"]),
        pitch_deg=float(pitch_deg),
        roll_deg=float(view["roll_deg"]),
        principal_offset_px=tuple(view["principal_offset_px"]),
    )


def viewpoint_frames(n_frames: int, k: int) -> np.ndarray:
    """``k`` frame indices of ``n_frames``, evenly spaced, the last (largest push) included."""
    return np.unique(np.rint(np.linspace(0, n_frames - 1, k + 1)[1:]).astype(int))


def render_viewpoint(
    result_npz,
    out_dir,
    view: dict,
    pitches_deg,
    *,
    params: RenderParams | None = None,
    extrusion_mm: float = schema_default("finger.extrusion_mm"),
    scene: dict | None = None,
    log_every_s: float = 30.0,
) -> dict:
    """Render ``view["frames_per_scene"]`` frames of a solver result at every pitch and
    every ``view["distances_mm"]``; returns the index (also written)."""
    from .pvrender import PyVistaPerspective

    params = params or RenderParams()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "index.json").unlink(missing_ok=True)
    for stale in out_dir.glob("*.png"):
        stale.unlink()
    res = resample_frames(load_fea_result(result_npz), params.frames_per_scene)
    frames = viewpoint_frames(res.n_frames, int(view["frames_per_scene"]))
    views = [(float(d), float(p)) for d in view["distances_mm"] for p in pitches_deg]
    t0 = time.perf_counter()
    rows = []
    progress = Progress(
        log,
        f"viewpoint renders of {Path(result_npz).parent}",
        len(views) * len(frames),
        log_every_s,
    )
    renderer = PyVistaPerspective(res.mesh, params, extrusion_mm, int(view["supersample"]))
    try:
        for d, p in views:
            cam = viewpoint_camera(view, p, d)
            for k in frames:
                name = f"d{d:g}_p{p:g}_{k:04d}.png"
                write_png(out_dir / name, renderer.render(res.deformed_points(int(k)), cam))
                rows.append(
                    {
                        "image": name,
                        "distance_mm": d,
                        "pitch_deg": p,
                        "frame": int(k),
                        "displacement_mm": float(res.displacement_mm[k]),
                        "fx_N": float(res.fx_N[k]),
                        "fy_N": float(res.fy_N[k]),
                        "contact_y_mm": float(res.contact_y_mm[k]),
                    }
                )
                progress(len(rows), f"{d:g} mm, pitch {p:g} deg")
    finally:
        renderer.close()
    index = {
        "result": str(result_npz),
        "scene": dict(scene or {}),
        "view": dict(view),
        "pitches_deg": [float(p) for p in pitches_deg],
        "n_frames": res.n_frames,
        "frames": rows,
        "renderer": "pyvista perspective",
        "seconds": time.perf_counter() - t0,
    }
    (out_dir / "index.json").write_text(json.dumps(index, indent=1))
    return index
