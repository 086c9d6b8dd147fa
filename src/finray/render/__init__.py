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

import importlib

_HOMES = {
    "camera": ("PinholeCamera", "set_vtk_camera"),
    "imageio": ("read_exr", "read_png", "write_exr", "write_png"),
    "params": ("RenderParams", "inverse_stress_transform", "stress_transform"),
    "perspective": ("PerspectiveRaster",),
    "raster": ("Rasterizer", "composite"),
    "result": ("FEAResult", "ResultError", "load_fea_result", "resample_frames"),
    "scene": ("SceneRenderer", "load_render_index", "read_render_frame", "render_scene"),
}
_WHERE = {name: module for module, names in _HOMES.items() for name in names}
__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
