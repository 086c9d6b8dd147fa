"""Throughput of the two render paths (called by the workflow into results/benchmarks/)."""
from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

from .imageio import write_exr, write_png
from .params import RenderParams
from .raster import Rasterizer, composite
from .result import load_fea_result


def _timed(fn, n: int) -> float:
    """Mean ms per call over n calls (after one warm-up call)."""
    fn(0)
    t = time.perf_counter()
    for k in range(n):
        fn(k)
    return (time.perf_counter() - t) / max(n, 1) * 1000.0


def benchmark(result_npz: str | Path, *, params: RenderParams | None = None,
              n_frames: int = 20, pitch_deg: float = 15.0, extrusion_mm: float = 20.0,
              pyvista: bool = True) -> dict:
    """Milliseconds per frame and frames per second per core of each render path.

    Single-threaded by construction (numba kernels are serial; Mesa's llvmpipe is
    held to one thread, ``LP_NUM_THREADS=1``). Frames cycle through the result's
    frames. Reported (all ms per frame):

    - ``raster_ms``: 2D rasteriser, coverage + stress + RGB composite (pitch 0)
    - ``raster_io_ms``: the same plus writing the PNG and the EXR
    - ``pyvista_front_ms``, ``pyvista_pitch_ms``: pyvista RGB frame at pitch 0 and
      at ``pitch_deg`` (render, read back, area-average); ``pyvista_init_s``: the
      plotter's start-up
    - ``*_fps_per_core``: 1000 / ms
    """
    params = params or RenderParams()
    res = load_fea_result(result_npz)
    nf = res.n_frames
    out: dict = {
        "n_frames_timed": n_frames, "image_px": [params.height, params.width],
        "supersample": params.supersample, "px_per_mm": params.px_per_mm,
        "n_nodes": int(len(res.points)), "n_triangles": int(len(res.triangles)),
    }
    rast = Rasterizer(res.mesh, params)

    def raster_frame(k):
        k %= nf
        cov, s, sa = rast.render(res.deformed_points(k), res.von_mises_MPa[k])
        return composite(cov, params), {"stress": s, "coverage": cov, "stress_area": sa}

    out["raster_ms"] = _timed(raster_frame, n_frames)
    with tempfile.TemporaryDirectory() as tmp:
        def raster_io(k):
            rgb, maps = raster_frame(k)
            write_png(Path(tmp) / "i.png", rgb)
            write_exr(Path(tmp) / "s.exr", maps)

        out["raster_io_ms"] = _timed(raster_io, n_frames)
    if pyvista:
        from .pvrender import PyVistaRenderer

        t = time.perf_counter()
        pvr = PyVistaRenderer(res.mesh, params, extrusion_mm=extrusion_mm, pitch_deg=0.0)
        out["pyvista_init_s"] = time.perf_counter() - t
        try:
            out["pyvista_front_ms"] = _timed(lambda k: pvr.render(res.deformed_points(k % nf)),
                                             n_frames)
            pvr.set_pitch(pitch_deg)
            out["pyvista_pitch_deg"] = pitch_deg
            out["pyvista_pitch_ms"] = _timed(lambda k: pvr.render(res.deformed_points(k % nf)),
                                             n_frames)
        finally:
            pvr.close()
    out["LP_NUM_THREADS"] = os.environ.get("LP_NUM_THREADS")
    for key in [k for k in out if k.endswith("_ms")]:
        out[key.replace("_ms", "_fps_per_core")] = 1000.0 / out[key] if out[key] > 0 else float("inf")
    return out


