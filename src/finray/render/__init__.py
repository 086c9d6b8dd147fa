"""Render stage: FEA frames -> camera images (PNG) and stress maps (EXR) in one pixel frame.

Public API (see each module's docstring):

- :func:`load_fea_result`, :func:`resample_frames` -- the solver's ``result.npz``
- :class:`RenderParams` -- window, resolution, colours, stress transform (config ``render``)
- :func:`render_scene` -- all frames of a scene: files (all, or ``files_per_scene`` of
  them) + ``index.json`` in a directory, every frame to an ``on_frame`` consumer
- :class:`Rasterizer` (front view, numba) and :class:`~finray.render.pvrender.PyVistaRenderer`
  (any pitch)
- :class:`PinholeCamera` (:mod:`~finray.render.camera`) and, through it, perspective views:
  :class:`PerspectiveRaster` (coverage, numba) and
  :class:`~finray.render.pvrender.PyVistaPerspective` (shaded image)

Their speed is measured by :func:`finray.benchmarks.render.benchmark`.
"""
from .camera import PinholeCamera, set_vtk_camera
from .imageio import read_exr, read_png, write_exr, write_png
from .params import RenderParams, inverse_stress_transform, stress_transform
from .perspective import PerspectiveRaster
from .raster import Rasterizer, composite
from .result import FEAResult, ResultError, load_fea_result, resample_frames
from .scene import SceneRenderer, load_render_index, read_render_frame, render_scene

__all__ = [
    "FEAResult", "PerspectiveRaster", "PinholeCamera", "Rasterizer", "RenderParams", "ResultError", "SceneRenderer",
    "composite", "inverse_stress_transform", "load_fea_result", "load_render_index",
    "read_exr", "read_png", "read_render_frame", "render_scene", "resample_frames",
    "set_vtk_camera", "stress_transform", "write_exr", "write_png",
]
