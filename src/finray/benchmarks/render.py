"""Throughput of the render paths and of the whole per-frame pipeline (called by the
workflow into results/benchmarks/)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from ..dataset.params import DatasetParams
from ..dataset.shards import FramePreparer
from ..render.imageio import write_exr, write_png
from ..render.params import RenderParams
from ..render.raster import Rasterizer, composite
from ..render.result import load_fea_result
from .timing import Stopwatch, time_calls
from ..schema import schema_default


def _timed(fn, n: int) -> tuple[float, float]:
    """Median wall and CPU (process) ms per call over ``n`` calls (after one warm-up)."""
    t = time_calls(fn, n)
    return t.wall_s * 1e3, t.cpu_s * 1e3


def benchmark(
    result_npz: str | Path,
    *,
    params: RenderParams | None = None,
    dataset_params=None,
    n_frames: int = 20,
    pitch_deg: float = 15.0,
    extrusion_mm: float = schema_default("finger.extrusion_mm"),
    pyvista: bool = True,
) -> dict:
    """Milliseconds per frame (median over the frames) and frames per second per core of each render path and
    of the whole per-frame pipeline of the workflow.

    Single-threaded by construction (numba kernels are serial; Mesa's llvmpipe is
    held to one thread, ``LP_NUM_THREADS=1``). Frames cycle through the result's
    frames. Reported (all ms per frame; ``*_ms`` wall, ``*_cpu_ms`` process CPU):

    - ``raster_ms``: 2D rasteriser, coverage + stress + RGB composite (pitch 0)
    - ``raster_io_ms``: the same plus writing the PNG and the EXR (what a frame with
      files costs; the workflow writes ``files_per_scene`` of them per view)
    - ``pipeline_raster_ms``: the workflow's frame at pitch 0: raster + composite +
      segmentation of the image + crop and area-average to every dataset size
      (:class:`~finray.dataset.shards.FramePreparer`), no files
    - ``pyvista_front_ms``, ``pyvista_pitch_ms``: pyvista RGB frame at pitch 0 and
      at ``pitch_deg`` (render, read back, area-average); ``pyvista_init_s``: the
      plotter's start-up
    - ``pipeline_pyvista_ms``: the workflow's frame at ``pitch_deg``: pyvista image
      + the front-view stress maps (raster) + segmentation and area-averages
    - ``*_fps_per_core``: 1000 / the wall ms (``*_cpu_fps_per_core``: / the CPU ms)
    """
    params = params or RenderParams()
    dparams = dataset_params or DatasetParams()
    res = load_fea_result(result_npz)
    nf = res.n_frames
    out: dict = {
        "n_frames_timed": n_frames,
        "image_px": [params.height, params.width],
        "supersample": params.supersample,
        "px_per_mm": params.px_per_mm,
        "n_nodes": int(len(res.points)),
        "n_triangles": int(len(res.triangles)),
        "dataset_sizes": [list(s) for s in dparams.sizes],
    }

    def put(name, wall_cpu):
        out[f"{name}_ms"], out[f"{name}_cpu_ms"] = wall_cpu

    rast = Rasterizer(res.mesh, params)
    prep = FramePreparer(params.shape, params.box_px(dparams.crop_x_mm, dparams.crop_y_mm), dparams)

    def raster_frame(k):
        k %= nf
        cov, s, sa = rast.render(res.deformed_points(k), res.von_mises_MPa[k])
        return composite(cov, params), {"stress": s, "coverage": cov, "stress_area": sa}

    put("raster", _timed(raster_frame, n_frames))
    with tempfile.TemporaryDirectory() as tmp:

        def raster_io(k):
            rgb, maps = raster_frame(k)
            write_png(Path(tmp) / "i.png", rgb)
            write_exr(Path(tmp) / "s.exr", maps)

        put("raster_io", _timed(raster_io, n_frames))
    put("pipeline_raster", _timed(lambda k: prep.prepare(*raster_frame(k)), n_frames))
    if pyvista:
        from ..render.pvrender import PyVistaRenderer

        with Stopwatch() as t:
            pvr = PyVistaRenderer(res.mesh, params, extrusion_mm=extrusion_mm, pitch_deg=0.0)
        out["pyvista_init_s"] = t.wall_s
        try:
            put(
                "pyvista_front", _timed(lambda k: pvr.render(res.deformed_points(k % nf)), n_frames)
            )
            pvr.set_pitch(pitch_deg)
            out["pyvista_pitch_deg"] = pitch_deg
            put(
                "pyvista_pitch", _timed(lambda k: pvr.render(res.deformed_points(k % nf)), n_frames)
            )

            def pyvista_pipeline(k):
                _, maps = raster_frame(k)
                prep.prepare(pvr.render(res.deformed_points(k % nf)), maps)

            put("pipeline_pyvista", _timed(pyvista_pipeline, n_frames))
        finally:
            pvr.close()
    out["LP_NUM_THREADS"] = os.environ.get("LP_NUM_THREADS")
    for key in [k for k in out if k.endswith("_ms")]:
        out[key[:-3] + "_fps_per_core"] = 1000.0 / out[key] if out[key] > 0 else float("inf")
    return out
