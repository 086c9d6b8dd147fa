"""FEA results as the render stage reads them (the solver's ``result.npz`` contract).

One file per scene, lengths in mm, forces in N (for the 20 mm extruded finger),
stresses in MPa:

==================  ==============  ====================================================
key                 shape / dtype   meaning
==================  ==============  ====================================================
points              (N, 2) float    reference node coordinates
triangles           (M, 6) int      quadratic triangles (corners CCW, then mid-sides)
boundary_edges      (E, 3) int      ``[a, b, mid]``, material on the left
displacement_mm     (F,) float      object travel of each frame (non-decreasing)
u_mm                (F, N, 2) f32   nodal displacements
von_mises_MPa       (F, N) f32      nodal von Mises stress (>= 0)
fx_N, fy_N          (F,) float      contact force on the finger
object_points_mm    (F, K, 2)       the object's boundary nodes each frame (figures only)
object_edges        (E_o, 2) int    segments between ``object_points_mm`` nodes
contact_y_mm        (F,) float      optional: height y (mm, clamped base at y=0) of the
                                    centroid of the object's contact forces, weighted by
                                    their magnitudes; NaN without contact force (a file
                                    without it reads as all NaN)
==================  ==============  ====================================================
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numba as nb
import numpy as np

from ..geometry.mesh import TriMesh
from ..errors import ResultError

REQUIRED_KEYS = (
    "points",
    "triangles",
    "boundary_edges",
    "displacement_mm",
    "u_mm",
    "von_mises_MPa",
    "fx_N",
    "fy_N",
    "object_points_mm",
    "object_edges",
)


@dataclass
class FEAResult:
    points: np.ndarray  # (N, 2) mm
    triangles: np.ndarray  # (M, 6) or (M, 3)
    boundary_edges: np.ndarray  # (E, 3)
    displacement_mm: np.ndarray  # (F,)
    u_mm: np.ndarray  # (F, N, 2)
    von_mises_MPa: np.ndarray  # (F, N)
    fx_N: np.ndarray  # (F,)
    fy_N: np.ndarray  # (F,)
    object_points_mm: np.ndarray  # (F, K, 2)
    object_edges: np.ndarray  # (E_o, 2)
    #: Index of each frame in the solver's output (fractional for interpolated frames).
    fea_frame: np.ndarray | None = None
    #: (F,) mm: height of the contact-force centroid (NaN without contact; all NaN
    #: when the file predates the key)
    contact_y_mm: np.ndarray | None = None

    def __post_init__(self):
        if self.fea_frame is None:
            self.fea_frame = np.arange(self.n_frames, dtype=float)
        if self.contact_y_mm is None:
            self.contact_y_mm = np.full(self.n_frames, np.nan)

    @property
    def n_frames(self) -> int:
        return len(self.displacement_mm)

    @property
    def mesh(self) -> TriMesh:
        """The finger's reference mesh (boundary tags unknown: all 0)."""
        return TriMesh(
            self.points,
            self.triangles,
            self.boundary_edges,
            np.zeros(len(self.boundary_edges), dtype=np.int64),
        )

    def deformed_points(self, frame: int) -> np.ndarray:
        """Deformed node positions (N, 2) mm of one frame."""
        return self.points + self.u_mm[frame].astype(np.float64)

    def frames(self, index) -> "FEAResult":
        """A result restricted to the given frame indices."""
        idx = np.asarray(index)
        return replace(
            self,
            displacement_mm=self.displacement_mm[idx],
            u_mm=self.u_mm[idx],
            von_mises_MPa=self.von_mises_MPa[idx],
            fx_N=self.fx_N[idx],
            fy_N=self.fy_N[idx],
            object_points_mm=self.object_points_mm[idx],
            fea_frame=self.fea_frame[idx],
            contact_y_mm=self.contact_y_mm[idx],
        )


def _check(res: FEAResult, path) -> None:
    n, f = len(res.points), res.n_frames

    def need(cond, msg):
        if not cond:
            raise ResultError(f"{path}: {msg}")

    need(
        res.points.ndim == 2 and res.points.shape[1] == 2,
        f"points has shape {res.points.shape}, expected (N, 2)",
    )
    need(
        res.triangles.ndim == 2 and res.triangles.shape[1] in (3, 6),
        f"triangles has shape {res.triangles.shape}, expected (M, 6) or (M, 3)",
    )
    need(res.triangles.min() >= 0 and res.triangles.max() < n, "triangles index outside points")
    need(
        res.boundary_edges.ndim == 2 and res.boundary_edges.shape[1] == 3,
        f"boundary_edges has shape {res.boundary_edges.shape}, expected (E, 3)",
    )
    need(f >= 1, "no frames")
    need(res.u_mm.shape == (f, n, 2), f"u_mm has shape {res.u_mm.shape}, expected {(f, n, 2)}")
    need(
        res.von_mises_MPa.shape == (f, n),
        f"von_mises_MPa has shape {res.von_mises_MPa.shape}, expected {(f, n)}",
    )
    need(
        res.fx_N.shape == (f,) and res.fy_N.shape == (f,), "fx_N and fy_N need one value per frame"
    )
    need(res.contact_y_mm.shape == (f,), "contact_y_mm needs one value per frame")
    need(
        res.object_points_mm.ndim == 3
        and res.object_points_mm.shape[0] == f
        and res.object_points_mm.shape[2] == 2,
        f"object_points_mm has shape {res.object_points_mm.shape}, expected ({f}, K, 2)",
    )
    k = res.object_points_mm.shape[1]
    need(
        res.object_edges.ndim == 2
        and res.object_edges.shape[1] == 2
        and (
            len(res.object_edges) == 0
            or (res.object_edges.min() >= 0 and res.object_edges.max() < k)
        ),
        "object_edges must be (E_o, 2) indices into object_points_mm",
    )
    need(
        np.all(np.isfinite(res.u_mm)) and np.all(np.isfinite(res.von_mises_MPa)),
        "u_mm or von_mises_MPa holds NaN or inf",
    )
    need(np.all(np.diff(res.displacement_mm) >= 0), "displacement_mm must be non-decreasing")


def load_fea_result(path: str | Path) -> FEAResult:
    """Read and check a solver ``result.npz``; raises :class:`ResultError` if malformed."""
    with np.load(path, allow_pickle=False) as f:
        missing = [k for k in REQUIRED_KEYS if k not in f.files]
        if missing:
            raise ResultError(f"{path}: missing keys {missing}")
        d = {k: f[k] for k in REQUIRED_KEYS}
        contact_y = (
            f["contact_y_mm"].astype(np.float64).ravel() if "contact_y_mm" in f.files else None
        )
    res = FEAResult(
        points=d["points"].astype(np.float64),
        triangles=d["triangles"].astype(np.int64),
        boundary_edges=d["boundary_edges"].astype(np.int64),
        displacement_mm=d["displacement_mm"].astype(np.float64).ravel(),
        u_mm=d["u_mm"].astype(np.float32, copy=False),
        von_mises_MPa=d["von_mises_MPa"].astype(np.float32, copy=False),
        fx_N=d["fx_N"].astype(np.float64).ravel(),
        fy_N=d["fy_N"].astype(np.float64).ravel(),
        object_points_mm=d["object_points_mm"].astype(np.float64),
        object_edges=d["object_edges"].astype(np.int64).reshape(-1, 2),
        contact_y_mm=contact_y,
    )
    _check(res, path)
    return res


def resample_frames(res: FEAResult, n_frames: int | None) -> FEAResult:
    """``n_frames`` frames evenly spaced in displacement, fields linearly interpolated.

    The first and last frames are kept exactly. ``None`` (or the number of frames
    the solver wrote, when their displacements are already even) returns ``res``.
    Nodal displacements, nodal stresses, forces and object positions are
    interpolated between the two solver frames that bracket each displacement
    (``contact_y_mm`` too: NaN where a bracketing frame has none). A truncated push
    (fewer frames, shorter travel) resamples its own travel.
    """
    if n_frames is None:
        return res
    if n_frames < 1:
        raise ValueError(f"n_frames must be >= 1, got {n_frames}")
    d = res.displacement_mm
    if res.n_frames == 1:
        return res.frames(np.zeros(n_frames, dtype=int))
    target = np.linspace(d[0], d[-1], n_frames) if n_frames > 1 else d[-1:]
    # bracket: d[i] <= t <= d[i + 1]; repeated displacements take the later frame
    i = np.clip(np.searchsorted(d, target, side="right") - 1, 0, res.n_frames - 2)
    span = d[i + 1] - d[i]
    w = np.where(span > 0, (target - d[i]) / np.where(span > 0, span, 1.0), 1.0)
    w = np.clip(w, 0.0, 1.0)

    def lerp(a):
        if a.dtype == np.float32 and a.ndim > 1:  # the big nodal fields: one pass
            out = np.empty((len(i),) + a.shape[1:], dtype=np.float32)
            _lerp_f32(a.reshape(len(a), -1), i, w, out.reshape(len(i), -1))
            return out
        wa = w.reshape((-1,) + (1,) * (a.ndim - 1))
        out = (1 - wa) * a[i].astype(np.float64) + wa * a[i + 1].astype(np.float64)
        return out.astype(a.dtype)

    def lerp_nan(a):
        """lerp, a frame met exactly (w 0 or 1) kept even where its neighbour is NaN."""
        return np.where(w <= 0, a[i], np.where(w >= 1, a[i + 1], (1 - w) * a[i] + w * a[i + 1]))

    return replace(
        res,
        displacement_mm=target,
        u_mm=lerp(res.u_mm),
        von_mises_MPa=lerp(res.von_mises_MPa),
        fx_N=lerp(res.fx_N),
        fy_N=lerp(res.fy_N),
        object_points_mm=lerp(res.object_points_mm),
        contact_y_mm=lerp_nan(res.contact_y_mm),
        fea_frame=(1 - w) * res.fea_frame[i] + w * res.fea_frame[i + 1],
    )


@nb.njit(cache=True)
def _lerp_f32(a, i, w, out):
    """out[k] = (1 - w[k]) a[i[k]] + w[k] a[i[k] + 1], evaluated in float64 and rounded
    to float32 (the same operations, in the same order, as the numpy expression)."""
    for k in range(out.shape[0]):
        wk = w[k]
        vk = 1.0 - wk
        for j in range(out.shape[1]):
            out[k, j] = np.float32(vk * np.float64(a[i[k], j]) + wk * np.float64(a[i[k] + 1, j]))
