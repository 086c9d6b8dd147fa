"""Render settings: the fixed camera window (one pixel frame per job), resolution,
colours and the stress transform.

Pixel frame
-----------
The image covers the window ``x in window_x_mm``, ``y in window_y_mm`` of the
camera's image plane at ``px_per_mm``. Pixel ``(row r, col c)`` has its centre at

    x = x0 + (c + 0.5) / px_per_mm,      y = y1 - (r + 0.5) / px_per_mm

(row 0 at the top). At pitch 0 the image plane is the finger's x-y plane. At pitch
theta the camera turns about the image's horizontal (x) axis through the window
centre ``(xc, yc, 0)``; a 3D point ``(x, y, z)`` (z towards the camera at pitch 0,
the finger spans ``z = +-extrusion/2``) lands at the image-plane point

    u = x,      v = yc + (y - yc) cos(theta) - z sin(theta)

(orthographic projection). Positive pitch puts the camera above the finger,
looking down on its tip. The window is the same for every frame, every scene and
every pitch of a job, so all images share one pixel frame.

Stress transform
----------------
Stress maps hold ``s = log10(1 + sigma_vM / stress_ref_MPa)`` (default reference
1 kPa, so 1 MPa -> 3.0, 10 MPa -> 4.0): monotone, 0 only at zero stress, no
clipping, inverse ``sigma = stress_ref_MPa * (10**s - 1)``. The nodal values are
transformed, then interpolated over the mesh. A pixel of the stress map holds the
mean of ``s`` over the material inside it where the finger covers at least half
of the pixel, and 0 elsewhere (background); the area average with background 0
(premultiplied by coverage) is kept alongside. See :func:`stress_transform`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..schema import schema_default


#: The default stress reference (MPa): the schema's ``render.stress_ref_MPa``.
STRESS_REF_MPa = schema_default("render.stress_ref_MPa")


def stress_transform(sigma_MPa, stress_ref_MPa: float = STRESS_REF_MPa):
    """``log10(1 + sigma / ref)``, negative stresses clipped to 0 (float64 in, same out)."""
    return np.log10(1.0 + np.maximum(sigma_MPa, 0.0) / stress_ref_MPa)


def inverse_stress_transform(s, stress_ref_MPa: float = STRESS_REF_MPa):
    """Von Mises stress (MPa) from the transformed value of a fully covered pixel."""
    return stress_ref_MPa * (10.0 ** np.asarray(s, dtype=np.float64) - 1.0)


@dataclass(frozen=True)
class RenderParams:
    """All settings of the render stage (config section ``render``; the defaults are
    the schema's)."""

    window_x_mm: tuple[float, float] = schema_default("render.window_x_mm")
    window_y_mm: tuple[float, float] = schema_default("render.window_y_mm")
    px_per_mm: float = schema_default("render.px_per_mm")
    #: Samples per pixel along each axis (rendered at px_per_mm * supersample, then
    #: area-averaged down).
    supersample: int = schema_default("render.supersample")
    stress_ref_MPa: float = schema_default("render.stress_ref_MPa")
    #: Colours in [0, 1]; away from x.5/255 so every 8-bit rounding agrees.
    finger_rgb: tuple[float, float, float] = schema_default("render.finger_rgb")
    background_rgb: tuple[float, float, float] = schema_default("render.background_rgb")
    object_rgb: tuple[float, float, float] = schema_default("render.object_rgb")
    #: Phong terms of the 3D view (headlight): a face square to the camera gets
    #: ``finger_rgb * (ambient + diffuse)``; keep the sum at 1 so that the front
    #: view of pyvista and of the 2D rasteriser have the same colour. A high
    #: ambient keeps the walls seen at a pitch (lit at a grazing angle) brighter
    #: than the segmentation's Otsu threshold.
    ambient: float = schema_default("render.ambient")
    diffuse: float = schema_default("render.diffuse")
    #: Frames per scene, evenly spaced in displacement and interpolated between
    #: the solver's frames; None takes the solver's frames as they are.
    frames_per_scene: int | None = schema_default("render.frames_per_scene")
    #: How many of the frames are also written as PNG + EXR files (evenly spaced,
    #: first and last included; see :func:`written_frames`); None writes all.
    #: Frames not written still reach a consumer of :func:`~finray.render.scene.render_scene`
    #: (the dataset shard) in memory.
    files_per_scene: int | None = schema_default("render.files_per_scene")

    def __post_init__(self):
        for key in ("window_x_mm", "window_y_mm"):
            lo, hi = getattr(self, key)
            if not hi > lo:
                raise ValueError(f"render.{key}: [{lo}, {hi}] is empty")
        if self.px_per_mm <= 0:
            raise ValueError("render.px_per_mm must be > 0")
        if int(self.supersample) != self.supersample or self.supersample < 1:
            raise ValueError("render.supersample must be a positive integer")
        for key in ("window_x_mm", "window_y_mm"):
            lo, hi = getattr(self, key)
            n = (hi - lo) * self.px_per_mm
            if abs(n - round(n)) > 1e-6:
                raise ValueError(
                    f"render.{key}: the window ({hi - lo:g} mm) is not a whole number of "
                    f"pixels at px_per_mm={self.px_per_mm:g} ({n:g})"
                )
        if self.stress_ref_MPa <= 0:
            raise ValueError("render.stress_ref_MPa must be > 0")
        if self.frames_per_scene is not None and self.frames_per_scene < 1:
            raise ValueError("render.frames_per_scene must be >= 1 or null")
        if self.files_per_scene is not None and self.files_per_scene < 0:
            raise ValueError("render.files_per_scene must be >= 0 or null")

    @classmethod
    def from_config(cls, section: dict | None) -> "RenderParams":
        """From the config's ``render`` section; keys this class does not know are ignored
        (the workflow keeps its own keys, e.g. ``pitches_deg``, in the same section)."""
        section = dict(section or {})
        names = {f.name for f in fields(cls)}
        kw = {}
        for k, v in section.items():
            if k in names:
                kw[k] = tuple(v) if isinstance(v, list) else v
        return cls(**kw)

    # ------------------------------------------------------------------ frame
    @property
    def width(self) -> int:
        return int(round((self.window_x_mm[1] - self.window_x_mm[0]) * self.px_per_mm))

    @property
    def height(self) -> int:
        return int(round((self.window_y_mm[1] - self.window_y_mm[0]) * self.px_per_mm))

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width) in pixels."""
        return self.height, self.width

    @property
    def centre_mm(self) -> tuple[float, float]:
        return (
            0.5 * (self.window_x_mm[0] + self.window_x_mm[1]),
            0.5 * (self.window_y_mm[0] + self.window_y_mm[1]),
        )

    def project(self, xyz: np.ndarray, pitch_deg: float = 0.0) -> np.ndarray:
        """Image-plane coordinates (u, v) in mm of 3D points (..., 3) at a pitch."""
        t = np.radians(pitch_deg)
        yc = self.centre_mm[1]
        u = xyz[..., 0]
        v = yc + (xyz[..., 1] - yc) * np.cos(t) - xyz[..., 2] * np.sin(t)
        return np.stack([u, v], axis=-1)

    def box_px(
        self, x_mm: tuple[float, float], y_mm: tuple[float, float]
    ) -> tuple[float, float, float, float]:
        """A window in mm as pixel edges ``(col0, row0, col1, row1)`` (floats; the
        pixel grid's edges sit at integers)."""
        return (
            (x_mm[0] - self.window_x_mm[0]) * self.px_per_mm,
            (self.window_y_mm[1] - y_mm[1]) * self.px_per_mm,
            (x_mm[1] - self.window_x_mm[0]) * self.px_per_mm,
            (self.window_y_mm[1] - y_mm[0]) * self.px_per_mm,
        )

    def written_frames(self, n_frames: int) -> np.ndarray:
        """Indices (sorted, unique) of the frames of an ``n_frames`` scene written as
        files: all if ``files_per_scene`` is None, else that many evenly spaced ones
        (first and last included, so a figure's last frame always has its files)."""
        if self.files_per_scene is None or self.files_per_scene >= n_frames:
            return np.arange(n_frames)
        if self.files_per_scene == 0:
            return np.zeros(0, dtype=int)
        if self.files_per_scene == 1:
            return np.array([n_frames - 1])
        return np.unique(np.rint(np.linspace(0, n_frames - 1, self.files_per_scene)).astype(int))

    def to_dict(self) -> dict:
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = list(v) if isinstance(v, tuple) else v
        out["width_px"], out["height_px"] = self.width, self.height
        return out
