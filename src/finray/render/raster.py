"""Direct 2D rasteriser of the front (pitch 0, orthographic) view.

The finger's P2 triangles are split into four linear ones (``linear_triangles``)
so that curved ribs keep their shape. Each pixel is sampled on a regular
``supersample x supersample`` grid; a sample is inside a triangle by the edge
functions with a top-left tie rule (a sample on an edge shared by two triangles
counts once), so the coverage of a pixel is the fraction of its samples inside
the finger and adjacent triangles neither overlap nor leave cracks.

Stress: the nodal von Mises stress is transformed with
:func:`~finray.render.params.stress_transform` (log scale), interpolated
barycentrically over the linear sub-triangles at each sample and averaged over
the pixel's samples. (Transforming at the nodes rather than at each sample saves
a logarithm per sample; the two differ only by the stress variation across one
sub-triangle, ~0.25 mm at the default mesh.) See :meth:`Rasterizer.render` for
the three maps returned.

The samples are accumulated straight into the output-resolution buffers, so the
cost grows with the finger's area in samples, not with the window. The result
matches pyvista's front view (same window, same pixel centres; tested).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..geometry.mesh import TriMesh
from ..geometry.surface import linear_triangles
from .params import RenderParams, stress_transform


@nb.njit(cache=True, inline="always")
def _edge_coeffs(px, py, a, b):
    """(A, B, C) of the edge function E(x, y) = A x + B y + C of a->b (> 0 on its left
    in a y-down frame), built from the lower node index first and then negated if
    needed, so that the two triangles sharing an edge get exactly opposite values
    at every sample (branch-free: the sign is a float +-1)."""
    lo = min(a, b)
    hi = max(a, b)
    sgn = 1.0 if a < b else -1.0
    dx = px[hi] - px[lo]
    dy = py[hi] - py[lo]
    return -dy * sgn, dx * sgn, (dy * px[lo] - dx * py[lo]) * sgn


@nb.njit(cache=True, inline="always")
def _owns(px, py, a, b):
    """Tie rule: a sample exactly on edge a->b belongs to this triangle iff the edge
    points down (or, horizontal, left); the neighbour traverses it the other way."""
    dy = py[b] - py[a]
    dx = px[b] - px[a]
    return (dy > 0) | ((dy == 0) & (dx < 0))


@nb.njit(cache=True, error_model="numpy")
def _raster_kernel(px, py, tris, vals, ss, count, acc):
    """Accumulate sample counts and interpolated-value sums into (H, W) buffers.

    px, py: node positions in fine-sample coordinates (sample centres at integers);
    vals: the nodal values to interpolate (the transformed stress). A sample is
    inside if all three edge functions are > 0, or == 0 on an edge the triangle owns.
    """
    hf = count.shape[0] * ss
    wf = count.shape[1] * ss
    cell = np.arange(max(hf, wf)) // ss  # sample index -> pixel index
    for t in range(tris.shape[0]):
        a = tris[t, 0]
        b = tris[t, 1]
        c = tris[t, 2]
        ax = px[a]
        ay = py[a]
        bx = px[b]
        by = py[b]
        cx = px[c]
        cy = py[c]
        area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if area == 0.0:
            continue
        x0 = max(int(math.ceil(min(ax, bx, cx))), 0)
        x1 = min(int(math.floor(max(ax, bx, cx))), wf - 1)
        y0 = max(int(math.ceil(min(ay, by, cy))), 0)
        y1 = min(int(math.floor(max(ay, by, cy))), hf - 1)
        if x0 > x1 or y0 > y1:
            continue
        if area < 0.0:  # make it positively oriented in sample space
            b, c = c, b
            area = -area
        # E_bc weighs node a, E_ca node b, E_ab node c
        A0, B0, C0 = _edge_coeffs(px, py, b, c)
        A1, B1, C1 = _edge_coeffs(px, py, c, a)
        A2, B2, C2 = _edge_coeffs(px, py, a, b)
        o0 = _owns(px, py, b, c)
        o1 = _owns(px, py, c, a)
        o2 = _owns(px, py, a, b)
        inv_area = 1.0 / area
        va = vals[a] * inv_area
        vb = vals[b] * inv_area
        vc = vals[c] * inv_area
        for j in range(y0, y1 + 1):
            sy = float(j)
            r0 = B0 * sy + C0
            r1 = B1 * sy + C1
            r2 = B2 * sy + C2
            r = cell[j]
            for i in range(x0, x1 + 1):
                sx = float(i)
                w0 = A0 * sx + r0
                w1 = A1 * sx + r1
                w2 = A2 * sx + r2
                inside = (
                    ((w0 > 0.0) | ((w0 == 0.0) & o0))
                    & ((w1 > 0.0) | ((w1 == 0.0) & o1))
                    & ((w2 > 0.0) | ((w2 == 0.0) & o2))
                )
                q = cell[i]
                count[r, q] += inside
                acc[r, q] += inside * (w0 * va + w1 * vb + w2 * vc)


@nb.njit(cache=True)
def _finalise_kernel(count, acc, n, coverage, stress, stress_area):
    """Per pixel: coverage = min(count, n) / n; stress_area = acc / max(count, n)
    (overlapping material counts once); stress = acc / count where 2 count >= n."""
    for r in range(count.shape[0]):
        for q in range(count.shape[1]):
            c = count[r, q]
            a = acc[r, q]
            coverage[r, q] = min(c, n) / n
            stress_area[r, q] = a / max(c, n)
            stress[r, q] = a / c if 2 * c >= n and c > 0 else 0.0


@nb.njit(cache=True)
def _composite_kernel(coverage, bg, fg, out):
    for r in range(coverage.shape[0]):
        for q in range(coverage.shape[1]):
            c = coverage[r, q]
            for k in range(3):
                v = bg[k] + c * (fg[k] - bg[k])
                out[r, q, k] = min(max(np.rint(v), 0.0), 255.0)


@nb.njit(cache=True)
def _polygon_kernel(px, py, edges, ss, count):
    """Even-odd scanline fill of the region bounded by segments (figures: the object)."""
    hf = count.shape[0] * ss
    wf = count.shape[1] * ss
    xs = np.empty(edges.shape[0], dtype=np.float64)
    for j in range(hf):
        sy = float(j)
        n = 0
        for e in range(edges.shape[0]):
            ya = py[edges[e, 0]]
            yb = py[edges[e, 1]]
            if (ya <= sy < yb) or (yb <= sy < ya):
                xa = px[edges[e, 0]]
                xb = px[edges[e, 1]]
                xs[n] = xa + (sy - ya) * (xb - xa) / (yb - ya)
                n += 1
        if n < 2:
            continue
        srt = np.sort(xs[:n])
        for k in range(0, n - 1, 2):
            i0 = max(int(math.ceil(srt[k])), 0)
            i1 = min(int(math.ceil(srt[k + 1])) - 1, wf - 1)
            for i in range(i0, i1 + 1):
                count[j // ss, i // ss] += 1


class Rasterizer:
    """Front-view rasteriser of one finger mesh in one pixel frame (reuse per job)."""

    def __init__(self, mesh: TriMesh, params: RenderParams | None = None):
        self.params = params or RenderParams()
        self.tris = np.ascontiguousarray(linear_triangles(mesh), dtype=np.int64)
        self.n_nodes = len(mesh.points)
        p = self.params
        self._scale = p.px_per_mm * p.supersample
        self._count = np.zeros(p.shape, dtype=np.int32)
        self._acc = np.zeros(p.shape, dtype=np.float64)

    def _sample_coords(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = self.params
        px = (xy[:, 0] - p.window_x_mm[0]) * self._scale - 0.5
        py = (p.window_y_mm[1] - xy[:, 1]) * self._scale - 0.5
        return np.ascontiguousarray(px, dtype=np.float64), np.ascontiguousarray(
            py, dtype=np.float64
        )

    def render(
        self, points2d: np.ndarray, von_mises_MPa: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(coverage, stress, stress_area)``, each (H, W) float32, of deformed nodes (N, 2) mm.

        - ``coverage``: fraction of the pixel covered by the finger;
        - ``stress``: the stress map -- mean of ``log10(1 + sigma / ref)`` over the
          material in the pixel where ``coverage >= 0.5``, 0 elsewhere (so its
          support is the half-coverage silhouette, the same pixels a threshold
          segmentation of the image finds);
        - ``stress_area``: the pixel's area average of the transformed stress with
          the background counted as 0 (premultiplied by coverage; exact to
          area-average further).

        All three are 0 if no stress is given, except coverage.
        """
        if len(points2d) != self.n_nodes:
            raise ValueError(f"expected {self.n_nodes} nodes, got {len(points2d)}")
        px, py = self._sample_coords(points2d)
        vals = (
            np.zeros(self.n_nodes)
            if von_mises_MPa is None
            else stress_transform(
                np.asarray(von_mises_MPa, dtype=np.float64), self.params.stress_ref_MPa
            )
        )
        self._count.fill(0)
        self._acc.fill(0.0)
        _raster_kernel(
            px, py, self.tris, vals, int(self.params.supersample), self._count, self._acc
        )
        shape = self.params.shape
        coverage = np.empty(shape, np.float32)
        stress = np.empty(shape, np.float32)
        stress_area = np.empty(shape, np.float32)
        _finalise_kernel(
            self._count, self._acc, int(self.params.supersample) ** 2, coverage, stress, stress_area
        )
        return coverage, stress, stress_area

    def polygon_coverage(self, points2d: np.ndarray, edges: np.ndarray) -> np.ndarray:
        """Coverage (H, W) float32 of the region bounded by ``edges`` (even-odd rule)."""
        px, py = self._sample_coords(np.asarray(points2d, dtype=np.float64))
        count = np.zeros(self.params.shape, dtype=np.int32)
        if len(edges):
            _polygon_kernel(
                px,
                py,
                np.ascontiguousarray(edges, dtype=np.int64),
                int(self.params.supersample),
                count,
            )
        n = self.params.supersample**2
        return (np.minimum(count, n) / n).astype(np.float32)


def composite(
    coverage: np.ndarray, params: RenderParams, object_coverage: np.ndarray | None = None
) -> np.ndarray:
    """RGB uint8 image (H, W, 3): finger colour over the background by coverage
    (and the object's colour on top, for figures).

    The colours are first quantised to 8 bits, as the GPU does, so that the area
    average of pyvista's supersampled front view gives the very same values.
    """
    bg = to_uint8(params.background_rgb).astype(np.float64)
    fg = to_uint8(params.finger_rgb).astype(np.float64)
    if object_coverage is None:
        out = np.empty(coverage.shape + (3,), np.uint8)
        _composite_kernel(np.ascontiguousarray(coverage, dtype=np.float64), bg, fg, out)
        return out
    img = bg + coverage[..., None].astype(np.float64) * (fg - bg)
    ob = to_uint8(params.object_rgb).astype(np.float64)
    oc = object_coverage[..., None].astype(np.float64)
    img = img * (1 - oc) + oc * ob
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def to_uint8(img01: np.ndarray) -> np.ndarray:
    """[0, 1] floats to uint8 by rounding (the same rule for every render path)."""
    return np.clip(np.rint(np.asarray(img01) * 255.0), 0, 255).astype(np.uint8)
