"""The emulated rig's studio: the 3D set a perspective camera films (pyvista, off screen).

In view: the extruded finger (its FEA mesh, deformed per frame), the clamp that holds
its base, the object on a six-axis sensor, and a textured back wall; lit by a key and
a fill light (an uneven background). The finger and clamp move with the gripper
(``shift_mm`` along x); the object and the sensor stand still. ``look["clutter"]``
adds things that a finder must not take for the finger (:data:`CLUTTER`): a
second object of the finger's colour (``object``: a box), a hand (``hand``: a
skin-coloured ellipsoid), each at ``centre_mm`` (x, y in the FEA's plane, in front
of the back wall at ``z_mm``) of ``size_mm`` (x, y extents), still or moving at
``velocity_mm_s`` (x, y; :meth:`Studio.at_time`: a person passing behind the rig);
they hide what lies behind them in the label view too.

Two plotters share the geometry: the colour view, and a label view where the finger is
white and unlit and everything else black, whose pixels are the true finger mask
(what is finger and not hidden by the object or the clamp).

The VTK camera is set from :class:`~finray.render.camera.PinholeCamera` by
:func:`~finray.render.camera.set_vtk_camera`: vertical view angle from ``fy``, the
principal point by the window centre, so that a world point lands on
:meth:`~finray.render.camera.PinholeCamera.project`'s pixel (tested).
"""

from __future__ import annotations

import numpy as np

from ..geometry.mesh import TriMesh
from ..geometry.surface import extrude
from ..render.camera import PinholeCamera, set_vtk_camera
from ..render.pvrender import vtk_cells  # (importing it: one core per job, EGL without X)


def prism(outline_xy: np.ndarray, z0: float, z1: float):
    """A closed prism (pyvista PolyData) of a simple polygon (N, 2) from z0 to z1 (mm)."""
    import pyvista as pv

    n = len(outline_xy)
    face = pv.PolyData(
        np.column_stack([outline_xy, np.full(n, z0)]), faces=np.concatenate([[n], np.arange(n)])
    )
    return face.extrude((0.0, 0.0, z1 - z0), capping=True).triangulate().clean()


#: The clutter kinds and their colours (linear RGB; None: the finger's).
CLUTTER = {"object": None, "hand": (0.80, 0.52, 0.40)}


def clutter_mesh(item: dict, finger_rgb):
    """A clutter item (see the module's text) as (pyvista mesh, colour)."""
    import pyvista as pv

    kind = item["kind"]
    if kind not in CLUTTER:
        raise ValueError(f"lab.look.clutter: kind {kind!r} is not one of {list(CLUTTER)}")
    (x, y), (w, h) = item["centre_mm"], item["size_mm"]
    z = float(item.get("z_mm", 0.0))
    if kind == "object":
        mesh = pv.Box((x - w / 2, x + w / 2, y - h / 2, y + h / 2, z - 10.0, z + 10.0))
    else:
        mesh = pv.ParametricEllipsoid(w / 2, h / 2, 12.0).translate((x, y, z), inplace=False)
    return mesh.triangulate(), CLUTTER[kind] or tuple(finger_rgb)


def wall_texture(shape=(256, 384), seed=0, base_rgb=(0.62, 0.60, 0.56)) -> np.ndarray:
    """An uneven, low-saturation wall (H, W, 3) uint8: blotches and grain around a
    grey-beige, as a lab's painted wall or board."""
    from scipy import ndimage as ndi

    rng = np.random.default_rng(seed)
    lum = ndi.gaussian_filter(rng.normal(0, 1, shape), 12) * 6.0
    lum += ndi.gaussian_filter(rng.normal(0, 1, shape), 2) * 0.8
    tint = ndi.gaussian_filter(rng.normal(0, 1, shape + (3,)), (20, 20, 0)) * 0.6
    img = np.asarray(base_rgb) * (1.0 + 0.25 * lum[..., None]) + 0.03 * tint
    return np.clip(img * 255, 0, 255).astype(np.uint8)


class Studio:
    """The studio of one take; :meth:`render` gives the colour and label images."""

    def __init__(
        self,
        finger: TriMesh,
        object_outline: np.ndarray,
        camera: PinholeCamera,
        look: dict,
        extrusion_mm: float,
        seed: int = 0,
    ):
        import pyvista as pv

        pv.OFF_SCREEN = True
        self.camera = camera
        self.surface = extrude(finger, extrusion_mm)
        size = (camera.width, camera.height)
        self.colour = pv.Plotter(off_screen=True, window_size=size, lighting="none")
        self.label = pv.Plotter(off_screen=True, window_size=size, lighting="none")
        for pl in (self.colour, self.label):
            pl.render_window.SetMultiSamples(0)  # the optics blur edges (see emulate)
        self.colour.set_background(look["background_rgb"])
        self.label.set_background((0.0, 0.0, 0.0))

        half = 0.5 * extrusion_mm
        self.finger = pv.PolyData(self.surface.points.copy(), vtk_cells(self.surface.faces))
        x0, x1 = float(finger.points[:, 0].min()), float(finger.points[:, 0].max())
        c = look["clamp_mm"]  # below the base, a little wider and deeper than the finger
        self.clamp_ref = pv.Box((x0 - c[0], x1 + c[0], -c[1], 0.0, -half - c[2], half + c[2]))
        self.clamp = self.clamp_ref.copy()
        ox = object_outline[:, 0].min()
        oy = 0.5 * (object_outline[:, 1].min() + object_outline[:, 1].max())
        obj = prism(object_outline, -0.5 * look["object_length_mm"], 0.5 * look["object_length_mm"])
        s = look["sensor_mm"]  # diameter, thickness: a disc along x, left of the object
        sensor = pv.Cylinder(
            center=(ox - 0.5 * s[1], oy, 0.0),
            direction=(1.0, 0.0, 0.0),
            radius=0.5 * s[0],
            height=s[1],
            resolution=64,
        ).triangulate()
        wz, ww, wh = look["wall_z_mm"], look["wall_size_mm"][0], look["wall_size_mm"][1]
        tx, ty, _ = camera.target
        wall = pv.Plane(center=(tx, ty, wz), direction=(0, 0, 1), i_size=ww, j_size=wh)
        wall.texture_map_to_plane(inplace=True)
        tex = pv.Texture(wall_texture(seed=seed))

        shade = dict(ambient=look["ambient"], diffuse=look["diffuse"], specular=0.0)
        a = self.colour.add_mesh(self.finger, color=look["finger_rgb"], **shade)
        a.GetProperty().BackfaceCullingOn()
        self.colour.add_mesh(self.clamp, color=look["clamp_rgb"], **shade)
        self.colour.add_mesh(obj, color=look["object_rgb"], **shade)
        self.colour.add_mesh(sensor, color=look["sensor_rgb"], **shade)
        self.colour.add_mesh(wall, texture=tex, **shade)
        items = look.get("clutter") or []
        clutter = [clutter_mesh(item, look["finger_rgb"]) for item in items]
        for mesh, rgb in clutter:
            self.colour.add_mesh(mesh, color=rgb, **shade)
        # moving clutter: (mesh, its points at t = 0, velocity (3,) mm/s)
        self.moving = [
            (mesh, mesh.points.copy(), np.r_[np.asarray(item["velocity_mm_s"], float), 0.0])
            for (mesh, _), item in zip(clutter, items)
            if any(item.get("velocity_mm_s") or ())
        ]
        for light in look["lights"]:
            self.colour.add_light(
                pv.Light(
                    position=light["position_mm"],
                    focal_point=camera.target,
                    intensity=light["intensity"],
                    light_type="scene light",
                )
            )
        flat = dict(ambient=1.0, diffuse=0.0, specular=0.0, lighting=False)
        a = self.label.add_mesh(self.finger, color=(1.0, 1.0, 1.0), **flat)
        a.GetProperty().BackfaceCullingOn()
        for mesh in (self.clamp, obj, sensor, *(m for m, _ in clutter)):
            self.label.add_mesh(mesh, color=(0.0, 0.0, 0.0), **flat)

        span = float(np.linalg.norm(np.asarray(camera.position) - np.asarray(camera.target)))
        self.far_mm = span - wz + 50.0
        self.window = (0, 0, camera.width, camera.height)
        self._pixels = None
        for pl in (self.colour, self.label):
            pl.show(auto_close=False)  # sets up the context; frames only render()
            self._set_camera(pl)

    def set_window(self, u0: int, v0: int, width: int, height: int) -> None:
        """Render only the box of the full image with its top-left pixel at column
        ``u0``, row ``v0``: the same projection, pixel for pixel (a smaller viewport
        whose view angle and window centre keep each ray)."""
        self.window = (int(u0), int(v0), int(width), int(height))
        for pl in (self.colour, self.label):
            pl.window_size = (int(width), int(height))
            self._set_camera(pl)
        self._pixels = None

    def _set_camera(self, pl) -> None:
        set_vtk_camera(pl.camera, self.camera, self.window, (10.0, self.far_mm))

    def _grab(self, pl) -> np.ndarray:
        from vtkmodules.util.numpy_support import vtk_to_numpy
        from vtkmodules.vtkCommonCore import vtkUnsignedCharArray

        pl.render()
        w, h = self.window[2:]
        if self._pixels is None:
            self._pixels = vtkUnsignedCharArray()
        pl.render_window.GetPixelData(0, 0, w - 1, h - 1, 0, self._pixels, 0)
        return vtk_to_numpy(self._pixels).reshape(h, w, 3)[::-1]

    def pose(self, points2d: np.ndarray, shift_mm: float) -> None:
        """The finger's deformed 2D nodes (N, 2) (FEA frame, mm), moved ``shift_mm``
        along x with the clamp."""
        pts = self.surface.deformed(np.asarray(points2d, dtype=np.float64))
        pts[:, 0] += shift_mm
        self.finger.points = pts
        clamp = self.clamp_ref.points.copy()
        clamp[:, 0] += shift_mm
        self.clamp.points = clamp

    def at_time(self, t_s: float) -> None:
        """Moving clutter where it is at time ``t_s`` (s) of the take."""
        for mesh, ref, velocity in self.moving:
            mesh.points = ref + t_s * velocity

    def render_colour(self) -> np.ndarray:
        """The pinhole colour image (h, w, 3) uint8 of the current pose and window
        (a view of a buffer the next render overwrites)."""
        return self._grab(self.colour)

    def render_mask(self) -> np.ndarray:
        """The true finger mask (h, w) bool of the current pose and window (pinhole)."""
        return self._grab(self.label)[..., 0] > 127

    def close(self) -> None:
        self.colour.close()
        self.label.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
