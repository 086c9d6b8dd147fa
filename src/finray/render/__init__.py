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

The names below load their module on first use (PEP 562, as :mod:`finray.train`), so that
a reader of one module (the dataset's shard reader: ``render.camera_views``,
``render.params``) does not load the rasterisers, the meshing library or VTK.
"""

from __future__ import annotations

from ..lazy import lazy_exports

_HOMES = {
    "camera": ("PinholeCamera", "set_vtk_camera"),
    "imageio": ("read_exr", "read_png", "write_exr", "write_png"),
    "params": ("RenderParams", "inverse_stress_transform", "stress_transform"),
    "perspective": ("PerspectiveRaster",),
    "raster": ("Rasterizer", "composite"),
    "result": ("FEAResult", "ResultError", "load_fea_result", "resample_frames"),
    "scene": ("SceneRenderer", "load_render_index", "read_render_frame", "render_scene"),
}
__getattr__, __dir__, __all__ = lazy_exports(__name__, _HOMES, globals())
