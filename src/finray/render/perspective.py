"""The extruded finger seen through a pinhole camera (numba), the fast counterpart of
:class:`~finray.render.pvrender.PyVistaPerspective` for the training views:
:meth:`PerspectiveRaster.coverage` (the silhouette) and :meth:`PerspectiveRaster.image`
(the shaded image, what the camera views segment).

The closed, outward-oriented surface of :func:`~finray.geometry.surface.extrude` is
deformed per frame (front and back caps, side walls), its vertices are projected with
the camera's pinhole (:meth:`~finray.render.camera.PinholeCamera.project`; lens
distortion is not applied: this is the pinhole image, as the pyvista path draws it),
and the faces turned away from the camera are culled. A ray that meets a closed
surface enters it through a face that faces the camera, so the silhouette is the union
of the camera-facing faces' projections: coverage needs no depth test (depth would
only matter for shading or for what covers what inside the silhouette).

Each pixel is sampled on a regular ``supersample x supersample`` grid at the sub-pixel
centres (the samples of a render at ``supersample`` x the resolution, see
:meth:`~finray.render.camera.PinholeCamera.scaled`); a sample is set if it lies in any
camera-facing triangle (edge functions, inclusive; the two triangles sharing an edge
get exactly opposite edge values, so a sample on it is in at least one: no cracks),
and a pixel's coverage is its count of set samples / supersample^2. The work is
confined to the smallest pixel window holding the projected surface.

The image adds what segmentation sees: a depth test per sample (1/z interpolated, which
is exact under perspective) keeps the nearest camera-facing face, flat-shaded by the
headlight as VTK shades it, so side walls seen at a grazing angle are darker than the
front face and a threshold cuts them where it cuts them in a pyvista render
(``tests/render/test_perspective.py`` compares the two pixel for pixel and after segmentation).
Camera-facing walls overlap often (a rib's top face behind the outer wall at a pitch):
painting them in any order without the depth test shades a fifth of a pitched view's
pixels wrongly.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..geometry.mesh import TriMesh
from ..geometry.surface import extrude
from .camera import PinholeCamera
from .raster import _edge_coeffs
from ..schema import schema_default

#: The most samples a coverage window may hold (a finger filling a camera's view at
#: supersample 4 needs a few million; more is a camera inside or at the finger).
MAX_SAMPLES = 1 << 28


@nb.njit(cache=True, inline="always")
def _sample_box(su, sv, a, b, c, hf, wf):
    """The samples (x0..x1, y0..y1, inclusive, clipped to the buffer) under triangle abc."""
    x0 = max(int(math.ceil(min(su[a], su[b], su[c]))), 0)
    x1 = min(int(math.floor(max(su[a], su[b], su[c]))), wf - 1)
    y0 = max(int(math.ceil(min(sv[a], sv[b], sv[c]))), 0)
    y1 = min(int(math.floor(max(sv[a], sv[b], sv[c]))), hf - 1)
    return x0, x1, y0, y1


@nb.njit(cache=True, error_model="numpy")
def _cover_kernel(su, sv, faces, buf):
    """Set ``buf`` (hf, wf) uint8 to 1 at the samples inside a camera-facing face.

    su, sv: the vertices' projections in sample coordinates (sample centres at
    integers). A face (outward normal, counter-clockwise seen from outside) faces the
    camera iff its projection is clockwise in this y-down frame: signed area < 0.
    """
    hf, wf = buf.shape
    for t in range(faces.shape[0]):
        a = faces[t, 0]
        b = faces[t, 1]
        c = faces[t, 2]
        area = (su[b] - su[a]) * (sv[c] - sv[a]) - (sv[b] - sv[a]) * (su[c] - su[a])
        if area >= 0.0:  # turned away (or edge-on: it covers nothing)
            continue
        x0, x1, y0, y1 = _sample_box(su, sv, a, b, c, hf, wf)
        if x0 > x1 or y0 > y1:
            continue
        b, c = c, b  # positively oriented: inside <=> all three edge values >= 0
        A0, B0, C0 = _edge_coeffs(su, sv, b, c)
        A1, B1, C1 = _edge_coeffs(su, sv, c, a)
        A2, B2, C2 = _edge_coeffs(su, sv, a, b)
        for j in range(y0, y1 + 1):
            sy = float(j)
            r0 = B0 * sy + C0
            r1 = B1 * sy + C1
            r2 = B2 * sy + C2
            for i in range(x0, x1 + 1):
                sx = float(i)
                inside = (A0 * sx + r0 >= 0.0) & (A1 * sx + r1 >= 0.0) & (A2 * sx + r2 >= 0.0)
                buf[j, i] |= inside


@nb.njit(cache=True)
def _count_kernel(buf, ss, cov):
    """cov (h, w) = the number of set samples in each ss x ss block of buf / ss^2."""
    h, w = cov.shape
    inv = 1.0 / (ss * ss)
    row = np.zeros(w, dtype=np.int32)
    for r in range(h):
        row[:] = 0
        for k in range(ss):
            line = buf[r * ss + k]
            for q in range(w):
                for m in range(ss):
                    row[q] += line[q * ss + m]
        for q in range(w):
            cov[r, q] = row[q] * inv


@nb.njit(cache=True, error_model="numpy")
def _depth_kernel(su, sv, inv_z, faces, depth, owner):
    """Z-buffer: at each sample inside a camera-facing face, keep the nearest face
    (largest 1/z, which is affine in screen space: perspective-correct) in ``owner``
    (-1: background). ``depth`` (hf, wf) float32 holds 1/z (0 = infinitely far)."""
    hf, wf = depth.shape
    for t in range(faces.shape[0]):
        a = faces[t, 0]
        b = faces[t, 1]
        c = faces[t, 2]
        area = (su[b] - su[a]) * (sv[c] - sv[a]) - (sv[b] - sv[a]) * (su[c] - su[a])
        if area >= 0.0:
            continue
        x0, x1, y0, y1 = _sample_box(su, sv, a, b, c, hf, wf)
        if x0 > x1 or y0 > y1:
            continue
        b, c = c, b
        A0, B0, C0 = _edge_coeffs(su, sv, b, c)  # weighs a
        A1, B1, C1 = _edge_coeffs(su, sv, c, a)  # weighs b
        A2, B2, C2 = _edge_coeffs(su, sv, a, b)  # weighs c
        inv_area = 1.0 / -area
        za = inv_z[a] * inv_area
        zb = inv_z[b] * inv_area
        zc = inv_z[c] * inv_area
        for j in range(y0, y1 + 1):
            sy = float(j)
            r0 = B0 * sy + C0
            r1 = B1 * sy + C1
            r2 = B2 * sy + C2
            for i in range(x0, x1 + 1):
                sx = float(i)
                e0 = A0 * sx + r0
                e1 = A1 * sx + r1
                e2 = A2 * sx + r2
                if e0 >= 0.0 and e1 >= 0.0 and e2 >= 0.0:
                    iz = e0 * za + e1 * zb + e2 * zc
                    if iz > depth[j, i]:
                        depth[j, i] = iz
                        owner[j, i] = t


@nb.njit(cache=True)
def _face_colours(pts, faces, fwd, rgb, ambient, diffuse, out):
    """out (F, 3): each face's 8-bit colour, ``rgb`` x (ambient + diffuse x max(0, -n.fwd))
    for its unit outward normal n (flat shading by a headlight along ``fwd``)."""
    for t in range(faces.shape[0]):
        a = faces[t, 0]
        b = faces[t, 1]
        c = faces[t, 2]
        ux = pts[b, 0] - pts[a, 0]
        uy = pts[b, 1] - pts[a, 1]
        uz = pts[b, 2] - pts[a, 2]
        vx = pts[c, 0] - pts[a, 0]
        vy = pts[c, 1] - pts[a, 1]
        vz = pts[c, 2] - pts[a, 2]
        nx = uy * vz - uz * vy
        ny = uz * vx - ux * vz
        nz = ux * vy - uy * vx
        norm = math.sqrt(nx * nx + ny * ny + nz * nz)
        cos = -(nx * fwd[0] + ny * fwd[1] + nz * fwd[2]) / norm if norm > 0 else 0.0
        light = ambient + diffuse * max(cos, 0.0)
        for k in range(3):
            out[t, k] = np.rint(min(max(rgb[k] * light, 0.0), 1.0) * 255.0)


@nb.njit(cache=True)
def _colour_kernel(owner, ss, face_rgb, bg, out):
    """out (h, w, 3) uint8 = mean over each pixel's ss x ss samples of its owner face's
    colour (the background's where none), rounded."""
    h, w = out.shape[:2]
    inv = 1.0 / (ss * ss)
    for r in range(h):
        for q in range(w):
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            for k in range(ss):
                for m in range(ss):
                    t = owner[r * ss + k, q * ss + m]
                    if t < 0:
                        s0 += bg[0]
                        s1 += bg[1]
                        s2 += bg[2]
                    else:
                        s0 += face_rgb[t, 0]
                        s1 += face_rgb[t, 1]
                        s2 += face_rgb[t, 2]
            out[r, q, 0] = np.uint8(min(np.rint(s0 * inv), 255.0))
            out[r, q, 1] = np.uint8(min(np.rint(s1 * inv), 255.0))
            out[r, q, 2] = np.uint8(min(np.rint(s2 * inv), 255.0))


class PerspectiveRaster:
    """Coverage of one finger mesh, extruded, through any pinhole camera (reuse per job)."""

    def __init__(
        self,
        mesh: TriMesh,
        extrusion_mm: float = schema_default("finger.extrusion_mm"),
        supersample: int = 3,
        corners_only: bool = False,
    ):
        """``corners_only``: quadratic elements drawn as their corner triangles (and the
        boundary as chords between corner nodes): a fourth of the triangles; a rib's
        mid-side node lies off the chord by ~chord^2 / (8 R), microns for 1 mm elements,
        far below a camera pixel (the camera views use it; tests/render/test_perspective.py
        checks the silhouettes against pyvista's full surface)."""
        if int(supersample) < 1:
            raise ValueError(f"supersample must be >= 1, got {supersample}")
        if corners_only and mesh.order == 2:
            be = mesh.boundary_edges
            mesh = TriMesh(
                mesh.points,
                mesh.triangles[:, :3],
                np.column_stack([be[:, 0], be[:, 1], np.full(len(be), -1)]),
                mesh.boundary_tags,
            )
        self.surface = extrude(mesh, extrusion_mm)
        self.faces = np.ascontiguousarray(self.surface.faces, dtype=np.int64)
        self.n_nodes = len(mesh.points)
        self.supersample = int(supersample)
        self._buf = np.zeros(0, dtype=np.uint8)  # the sample buffer, grown as needed

    def coverage(
        self, points2d: np.ndarray, camera: PinholeCamera
    ) -> tuple[np.ndarray, tuple[int, int]]:
        """``(cov, (row0, col0))``: ``cov`` (h, w) float32 in [0, 1] is the fraction of each
        camera pixel covered by the extruded finger of deformed 2D nodes (N, 2) mm, over
        the smallest pixel window holding the whole projected surface plus a 1 px margin,
        not clipped to the camera's frame; ``(row0, col0)`` is the window's top-left
        pixel in the camera's pixel grid (may be negative or beyond the frame)."""
        _, _, su, sv, (row0, col0, h, w) = self._window(points2d, camera)
        ss = self.supersample
        n = h * w * ss * ss
        if self._buf.size < n:
            self._buf = np.zeros(n, dtype=np.uint8)
        buf = self._buf[:n].reshape(h * ss, w * ss)
        buf.fill(0)
        _cover_kernel(su, sv, self.faces, buf)
        cov = np.empty((h, w), dtype=np.float32)
        _count_kernel(buf, ss, cov)
        return cov, (row0, col0)

    def _window(self, points2d: np.ndarray, camera: PinholeCamera):
        """Deformed surface points (V, 3), their depths, sample coordinates and the window."""
        points2d = np.asarray(points2d, dtype=np.float64)
        if points2d.shape != (self.n_nodes, 2):
            raise ValueError(f"expected {self.n_nodes} nodes (N, 2), got shape {points2d.shape}")
        pts = self.surface.deformed(points2d)
        pc = camera.to_camera(pts)
        z = pc[:, 2]
        if not z.min() > 0.0:
            raise ValueError(
                f"the finger reaches behind the camera (nearest point {z.min():.1f} mm "
                "along its axis); move the camera away"
            )
        u = camera.fx * pc[:, 0] / z + camera.cx
        v = camera.fy * pc[:, 1] / z + camera.cy
        col0, col1 = int(np.floor(u.min() + 0.5)) - 1, int(np.floor(u.max() + 0.5)) + 1
        row0, row1 = int(np.floor(v.min() + 0.5)) - 1, int(np.floor(v.max() + 0.5)) + 1
        h, w = row1 - row0 + 1, col1 - col0 + 1
        ss = self.supersample
        if h * w * ss * ss > MAX_SAMPLES:
            raise ValueError(
                f"the finger spans {h} x {w} px in this camera's view "
                f"(over {MAX_SAMPLES} samples at supersample {ss}); move the camera away"
            )
        su = (u - col0 + 0.5) * ss - 0.5
        sv = (v - row0 + 0.5) * ss - 0.5
        return pts, z, su, sv, (row0, col0, h, w)

    def image(
        self, points2d: np.ndarray, camera: PinholeCamera, params
    ) -> tuple[np.ndarray, tuple[int, int]]:
        """``(rgb, (row0, col0))``: the finger as :class:`~finray.render.pvrender.PyVistaPerspective`
        draws it, over the window of :meth:`coverage`, (h, w, 3) uint8: at each sample
        the nearest camera-facing face (a depth test), flat-shaded by the
        headlight of :class:`~finray.render.params.RenderParams` (``finger_rgb`` x
        (``ambient`` + ``diffuse`` x cos of the angle between its normal and the view
        direction), 8-bit), the background ``background_rgb``, area-averaged over the
        samples; so that :func:`~finray.dataset.imageops.segment` meets the grey levels
        of a render (side walls seen at a grazing angle darker than the front face)."""
        from .raster import to_uint8

        pts, z, su, sv, (row0, col0, h, w) = self._window(points2d, camera)
        ss = self.supersample
        depth = np.zeros((h * ss, w * ss), dtype=np.float32)
        owner = np.full((h * ss, w * ss), -1, dtype=np.int32)
        _depth_kernel(su, sv, 1.0 / z, self.faces, depth, owner)
        face_rgb = np.empty((len(self.faces), 3))
        # the headlight shines along the view direction
        _face_colours(
            pts,
            self.faces,
            np.ascontiguousarray(camera.rotation()[2]),
            np.asarray(params.finger_rgb, dtype=np.float64),
            float(params.ambient),
            float(params.diffuse),
            face_rgb,
        )
        bg = to_uint8(np.asarray(params.background_rgb)).astype(np.float64)
        out = np.empty((h, w, 3), dtype=np.uint8)
        _colour_kernel(owner, ss, face_rgb, bg, out)
        return out, (row0, col0)
