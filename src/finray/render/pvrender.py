"""3D view of the extruded finger with pyvista (VTK), off screen.

One :class:`PyVistaRenderer` (one plotter, one OpenGL context) serves a whole job:
each frame only updates the surface points and re-renders. Multisampling is off
(on the software renderer it costs 3-4x); anti-aliasing comes from rendering at
``supersample`` times the resolution and area-averaging down, as in the 2D
rasteriser. :class:`PyVistaRenderer`: parallel (orthographic) projection, the camera
framing of :class:`~finray.render.params.RenderParams`; :class:`PyVistaPerspective`:
any :class:`~finray.render.camera.PinholeCamera`, pixel for pixel. A single headlight.

Back faces are culled: the extruded surface is closed and outward-oriented, so a
back face is always hidden behind a front face, and not drawing them (the caps
turned away from the camera) saves a third of the software renderer's time.

Mesa's software renderer (llvmpipe) starts one thread per core unless
``LP_NUM_THREADS`` says otherwise; this module sets it to 1 if unset (set it
before the first plotter is created to change it), so one job uses one core. Without
an X display, VTK is pointed at EGL (``VTK_DEFAULT_OPENGL_WINDOW``), unless set.
"""

from __future__ import annotations

import os

os.environ.setdefault("LP_NUM_THREADS", "1")
if not os.environ.get("DISPLAY"):
    # no X server: straight to EGL (VTK would try X first and warn on stderr)
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")

import numpy as np

from ..geometry.mesh import TriMesh
from ..geometry.surface import extrude
from .camera import PinholeCamera, set_vtk_camera
from .params import RenderParams
from .raster import to_uint8
from ..schema import schema_default

#: Distance of the camera from the window centre (mm); any value outside the scene
#: gives the same orthographic image.
CAMERA_DISTANCE_MM = 1000.0


def vtk_cells(tri: np.ndarray) -> np.ndarray:
    """VTK's flat cell array ``[n, i0, ..., n, ...]`` of (M, n) index rows."""
    return np.column_stack([np.full(len(tri), tri.shape[1]), tri]).ravel()


def _finger_plotter(surface, p: RenderParams, size: tuple[int, int]):
    """An off-screen plotter of ``size`` (W, H) px with the extruded finger ``surface``
    in its colour, a headlight, no multisampling and back faces culled (the renderers'
    one set-up); returns the plotter and the finger's PolyData (points updated per frame)."""
    import pyvista as pv

    pl = pv.Plotter(off_screen=True, window_size=size, lighting="none")
    pl.render_window.SetMultiSamples(0)
    pl.set_background(p.background_rgb)
    pl.add_light(pv.Light(light_type="headlight", intensity=1.0))
    poly = pv.PolyData(surface.points.copy(), vtk_cells(surface.faces))
    actor = pl.add_mesh(
        poly,
        color=p.finger_rgb,
        ambient=p.ambient,
        diffuse=p.diffuse,
        specular=0.0,
        smooth_shading=False,
        show_edges=False,
    )
    actor.GetProperty().BackfaceCullingOn()
    return pl, poly


class _Plotted:
    """A renderer that owns ``self.plotter`` (window ``self.size``, W x H px): renders
    and reads back a frame (:meth:`_grab`), closed by :meth:`close` or ``with``."""

    _pixels = None

    def _grab(self) -> np.ndarray:
        """Render and read back the frame (H, W, 3) uint8, row 0 at the top."""
        from vtkmodules.util.numpy_support import vtk_to_numpy
        from vtkmodules.vtkCommonCore import vtkUnsignedCharArray

        self.plotter.render()
        w, h = self.size
        if self._pixels is None:
            self._pixels = vtkUnsignedCharArray()
        self.plotter.render_window.GetPixelData(0, 0, w - 1, h - 1, 0, self._pixels, 0)
        return vtk_to_numpy(self._pixels).reshape(h, w, 3)[::-1]

    def close(self) -> None:
        self.plotter.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class PyVistaRenderer(_Plotted):
    """Off-screen renderer of one finger mesh (and optionally its object) for a job.

    ``render(points2d)`` returns the RGB image (H, W, 3) uint8 in the job's pixel
    frame at the current pitch (:meth:`set_pitch`).
    """

    def __init__(
        self,
        mesh: TriMesh,
        params: RenderParams | None = None,
        extrusion_mm: float = schema_default("finger.extrusion_mm"),
        pitch_deg: float = 0.0,
        object_edges: np.ndarray | None = None,
        n_object_points: int = 0,
    ):
        import pyvista as pv

        pv.OFF_SCREEN = True
        self.params = p = params or RenderParams()
        self.surface = extrude(mesh, extrusion_mm)
        self.extrusion_mm = extrusion_mm
        self.ss = int(p.supersample)
        self.size = (p.width * self.ss, p.height * self.ss)  # (W, H) in pixels
        self.plotter, self.poly = _finger_plotter(self.surface, p, self.size)
        pl = self.plotter
        self.object_poly = None
        if object_edges is not None and len(object_edges) and n_object_points:
            # the object's outline on the camera-side face of the finger, and its
            # walls through the extrusion (figures only)
            k = n_object_points
            zf = 0.5 * extrusion_mm + 0.05
            pts = np.zeros((2 * k, 3))
            pts[:k, 2], pts[k:, 2] = zf, -zf
            a, b = object_edges[:, 0], object_edges[:, 1]
            quads = np.column_stack([a, b, b + k, a + k])
            self.object_poly = pv.PolyData(pts, vtk_cells(quads))
            pl.add_mesh(
                self.object_poly,
                color=p.object_rgb,
                ambient=p.ambient,
                diffuse=p.diffuse,
                specular=0.0,
            )
            self.object_lines = pv.PolyData(pts[:k].copy(), lines=vtk_cells(object_edges))
            pl.add_mesh(
                self.object_lines, color=p.object_rgb, line_width=2 * self.ss, lighting=False
            )
        pl.enable_parallel_projection()
        # the first show() sets up the render window (and may reset the camera);
        # frames after it only call render()
        self.set_pitch(pitch_deg)
        pl.show(auto_close=False)
        self.set_pitch(pitch_deg)
        self._pixels = None

    def set_pitch(self, pitch_deg: float) -> None:
        """Camera pitch about the image's horizontal axis (deg, + looks down on the tip)."""
        p = self.params
        t = np.radians(pitch_deg)
        xc, yc = p.centre_mm
        cam = self.plotter.camera
        cam.focal_point = (xc, yc, 0.0)
        cam.position = (xc, yc + CAMERA_DISTANCE_MM * np.sin(t), CAMERA_DISTANCE_MM * np.cos(t))
        cam.up = (0.0, np.cos(t), -np.sin(t))
        cam.parallel_scale = 0.5 * (p.window_y_mm[1] - p.window_y_mm[0])
        span = max(p.window_y_mm[1] - p.window_y_mm[0], p.window_x_mm[1] - p.window_x_mm[0])
        cam.clipping_range = (
            CAMERA_DISTANCE_MM - 2 * span - self.extrusion_mm,
            CAMERA_DISTANCE_MM + 2 * span + self.extrusion_mm,
        )
        self.pitch_deg = float(pitch_deg)

    def render_fine(
        self, points2d: np.ndarray, object_points2d: np.ndarray | None = None
    ) -> np.ndarray:
        """The supersampled RGB frame (H*ss, W*ss, 3) uint8, row 0 at the top."""
        self.poly.points = self.surface.deformed(np.asarray(points2d, dtype=np.float64))
        if self.object_poly is not None and object_points2d is not None:
            k = len(object_points2d)
            pts = self.object_poly.points.copy()
            pts[:k, :2] = object_points2d
            pts[k:, :2] = object_points2d
            self.object_poly.points = pts
            self.object_lines.points = pts[:k].copy()
        return self._grab()

    def render(self, points2d: np.ndarray, object_points2d: np.ndarray | None = None) -> np.ndarray:
        """RGB image (H, W, 3) uint8: the fine frame area-averaged down."""
        fine = self.render_fine(points2d, object_points2d)
        return to_uint8(block_mean_u8(fine, self.ss) / 255.0)


class PyVistaPerspective(_Plotted):
    """Off-screen perspective renderer of one finger mesh, extruded, for a job: the
    finger alone in ``finger_rgb`` on ``background_rgb``, lit by a headlight with the
    ``ambient`` and ``diffuse`` terms of :class:`RenderParams` (as :class:`PyVistaRenderer`).

    ``render(points2d, camera)`` draws the pinhole image (no lens distortion) of any
    :class:`~finray.render.camera.PinholeCamera`, which may change between calls: at
    ``supersample`` (default ``params.supersample``) x its resolution through
    :meth:`~finray.render.camera.PinholeCamera.scaled`, then area-averaged down.
    """

    def __init__(
        self,
        mesh: TriMesh,
        params: RenderParams | None = None,
        extrusion_mm: float = schema_default("finger.extrusion_mm"),
        supersample: int | None = None,
    ):
        import pyvista as pv

        pv.OFF_SCREEN = True
        self.params = p = params or RenderParams()
        self.surface = extrude(mesh, extrusion_mm)
        self.n_nodes = len(mesh.points)
        self.ss = int(supersample or p.supersample)
        self.size = (64, 64)  # (W, H) in pixels; set per camera
        self.plotter, self.poly = _finger_plotter(self.surface, p, self.size)
        pl = self.plotter
        # the first show() sets up the render window (and may reset the camera);
        # frames after it set the camera and only call render()
        pl.show(auto_close=False)
        self._pixels = None

    def render_fine(self, points2d: np.ndarray, camera: PinholeCamera) -> np.ndarray:
        """The supersampled RGB frame (H*ss, W*ss, 3) uint8 of ``camera``, row 0 at the top."""
        points2d = np.asarray(points2d, dtype=np.float64)
        if points2d.shape != (self.n_nodes, 2):
            raise ValueError(f"expected {self.n_nodes} nodes (N, 2), got shape {points2d.shape}")
        pts = self.surface.deformed(points2d)
        z = camera.to_camera(pts)[:, 2]
        if not z.min() > 0.0:
            raise ValueError(
                f"the finger reaches behind the camera (nearest point {z.min():.1f} mm "
                "along its axis); move the camera away"
            )
        fine = camera.scaled(self.ss)
        size = (fine.width, fine.height)
        if size != self.size:
            self.plotter.window_size = size
            self.size = size
            self._pixels = None
        self.poly.points = pts
        # near and far planes around the finger (depth resolution is relative to them)
        set_vtk_camera(self.plotter.camera, fine, clipping=(0.5 * z.min(), 2.0 * z.max()))
        return self._grab()

    def render(self, points2d: np.ndarray, camera: PinholeCamera) -> np.ndarray:
        """RGB image (camera.height, camera.width, 3) uint8 of deformed 2D nodes (N, 2) mm."""
        return to_uint8(block_mean_u8(self.render_fine(points2d, camera), self.ss) / 255.0)


def block_mean_u8(img: np.ndarray, k: int) -> np.ndarray:
    """:func:`block_mean` of an (H*k, W*k, C) uint8 image, exactly (uint16 sums of
    strided rows, then columns -- no overflow for k <= 16 -- and one division),
    ~8x faster than the float reduction."""
    h, w = img.shape[0] // k, img.shape[1] // k
    rows = img[0 : h * k : k, : w * k].astype(np.uint16)
    for i in range(1, k):
        rows += img[i : h * k : k, : w * k]
    rows = rows.reshape(h, w, k, *img.shape[2:])
    out = rows[:, :, 0].copy()
    for i in range(1, k):
        out += rows[:, :, i]
    return out / float(k * k)


def block_mean(img: np.ndarray, k: int) -> np.ndarray:
    """Mean over k x k blocks of an (H*k, W*k, ...) array, float64."""
    h, w = img.shape[0] // k, img.shape[1] // k
    return img.reshape(h, k, w, k, *img.shape[2:]).mean(axis=(1, 3), dtype=np.float64)
