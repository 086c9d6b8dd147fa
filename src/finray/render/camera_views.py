"""Randomised pinhole cameras for the training views (config ``render.camera_views``).

Each training frame is also seen by one camera drawn from these ranges, replayable from
``(seed, scene id, frame)``: a D435i-class colour camera (one of its stream sizes,
mounted portrait so that the finger fills the long side, horizontal field of view near
the data sheet's 69.4 deg) 150-400 mm in front of the finger, raised by a pitch of
0-30 deg (looking down on the tip), turned a few degrees of yaw and roll, aimed at the
finger's middle within a few mm, with its principal point a few pixels off centre.
Lengths in mm, angles in deg, pixels as :class:`~finray.render.camera.PinholeCamera`.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, fields

import numpy as np

from .camera import PinholeCamera
from ..schema import schema_default

#: The columns of a drawn view (:meth:`CameraViews.sample`), as stored per frame in shards.
VIEW_COLUMNS = (
    "pitch_deg",
    "yaw_deg",
    "roll_deg",
    "distance_mm",
    "hfov_deg",
    "width_px",
    "height_px",
    "cx_offset_px",
    "cy_offset_px",
    "target_x_mm",
    "target_y_mm",
)


@dataclass(frozen=True)
class CameraViews:
    """Ranges ``[lo, hi]`` (drawn uniformly) of the training cameras."""

    seed: int = schema_default("render.camera_views.seed")
    pitch_deg: tuple[float, float] = schema_default("render.camera_views.pitch_deg")
    yaw_deg: tuple[float, float] = schema_default("render.camera_views.yaw_deg")
    roll_deg: tuple[float, float] = schema_default("render.camera_views.roll_deg")
    distance_mm: tuple[float, float] = schema_default("render.camera_views.distance_mm")
    #: Horizontal field of view of the (landscape) stream.
    hfov_deg: tuple[float, float] = schema_default("render.camera_views.hfov_deg")
    #: Stream sizes (width, height), one drawn per view; used portrait (rotated 90 deg).
    frames_px: tuple[tuple[int, int], ...] = schema_default("render.camera_views.frames_px")
    #: Principal point offset from the centre, each axis uniform in +-this (px).
    principal_offset_px: float = schema_default("render.camera_views.principal_offset_px")
    #: Where the camera aims (finger frame, mm), each axis within +-target_jitter_mm.
    target_mm: tuple[float, float] = schema_default("render.camera_views.target_mm")
    target_jitter_mm: float = schema_default("render.camera_views.target_jitter_mm")
    #: Samples per pixel along each axis of the raster (coverage at 1 / supersample^2).
    supersample: int = schema_default("render.camera_views.supersample")

    def __post_init__(self):
        for key in ("pitch_deg", "yaw_deg", "roll_deg", "distance_mm", "hfov_deg"):
            lo, hi = getattr(self, key)
            if hi < lo:
                raise ValueError(f"render.camera_views.{key}: [{lo}, {hi}] is empty")
        if self.distance_mm[0] <= 0:
            raise ValueError("render.camera_views.distance_mm must be > 0")
        if not self.frames_px:
            raise ValueError("render.camera_views.frames_px: no stream size")

    @classmethod
    def from_config(cls, section: dict | None) -> "CameraViews | None":
        """From ``render.camera_views`` (None or ``enabled: false``: no camera views)."""
        if not section or not section.get("enabled", True):
            return None
        names = {f.name for f in fields(cls)}
        kw = {}
        for k, v in section.items():
            if k in names:
                kw[k] = (
                    tuple(tuple(x) if isinstance(x, list) else x for x in v)
                    if isinstance(v, list)
                    else v
                )
        return cls(**kw)

    def sample(self, scene_id: str, frame: int) -> tuple[PinholeCamera, np.ndarray]:
        """The camera of one frame of one scene, and its row of :data:`VIEW_COLUMNS`."""
        rng = np.random.default_rng(
            [int(self.seed) & 0xFFFFFFFF, zlib.crc32(str(scene_id).encode()), int(frame)]
        )
        u = rng.random(11)

        def draw(rng_lo_hi, x):
            return rng_lo_hi[0] + x * (rng_lo_hi[1] - rng_lo_hi[0])

        pitch, yaw, roll = (
            draw(self.pitch_deg, u[0]),
            draw(self.yaw_deg, u[1]),
            draw(self.roll_deg, u[2]),
        )
        dist, hfov = draw(self.distance_mm, u[3]), draw(self.hfov_deg, u[4])
        w_land, h_land = self.frames_px[
            min(int(u[5] * len(self.frames_px)), len(self.frames_px) - 1)
        ]
        ox, oy = (
            (2 * u[6] - 1) * self.principal_offset_px,
            (2 * u[7] - 1) * self.principal_offset_px,
        )
        tx = self.target_mm[0] + (2 * u[8] - 1) * self.target_jitter_mm
        ty = self.target_mm[1] + (2 * u[9] - 1) * self.target_jitter_mm
        # portrait: the landscape stream's horizontal angle spans the image's height
        width, height = int(h_land), int(w_land)
        hfov_portrait = 2 * np.degrees(np.arctan(width / height * np.tan(np.radians(0.5 * hfov))))
        cam = PinholeCamera.looking_at(
            (tx, ty, 0.0),
            width=width,
            height=height,
            hfov_deg=hfov_portrait,
            distance_mm=dist,
            yaw_deg=yaw,
            pitch_deg=pitch,
            roll_deg=roll,
            principal_offset_px=(ox, oy),
        )
        row = np.array([pitch, yaw, roll, dist, hfov, width, height, ox, oy, tx, ty])
        return cam, row

    def to_dict(self) -> dict:
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = (
                [list(x) if isinstance(x, tuple) else x for x in v] if isinstance(v, tuple) else v
            )
        return out
