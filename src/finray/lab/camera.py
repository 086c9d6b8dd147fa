"""A colour camera: pinhole with lens distortion, exposure, sensor noise, lossy video.

Conventions: world in mm (the FEA's x right, y up the finger, z out of its front face);
pixel coordinates as OpenCV's: u right, v down, the centre of pixel (row i, column j)
at (u, v) = (j, i).

Distortion is the inverse Brown-Conrady model a RealSense colour stream reports: for
a pixel of the (distorted) image, with normalised coordinates ``x, y`` and
``r^2 = x^2 + y^2``, the undistorted ray is
``x_u = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)`` (y alike), so
each output pixel samples the pinhole render at one point (no iteration).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class PinholeCamera:
    """Intrinsics (px), distortion ``(k1, k2, p1, p2, k3)`` and pose (world mm)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    position: tuple[float, float, float]
    target: tuple[float, float, float]
    up: tuple[float, float, float]
    distortion: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)

    @classmethod
    def looking_at(cls, target_mm, *, width: int, height: int, hfov_deg: float,
                   distance_mm: float, yaw_deg: float = 0.0, pitch_deg: float = 0.0,
                   roll_deg: float = 0.0, principal_offset_px=(0.0, 0.0),
                   distortion=(0.0, 0.0, 0.0, 0.0, 0.0)) -> "PinholeCamera":
        """A camera ``distance_mm`` from ``target_mm`` on the finger's front side (+z),
        turned ``yaw_deg`` about y (towards +x), raised ``pitch_deg`` (looking down)
        and rolled ``roll_deg`` about its axis; square pixels from the horizontal FOV."""
        f = 0.5 * width / np.tan(np.radians(0.5 * hfov_deg))
        yaw, pitch, roll = np.radians([yaw_deg, pitch_deg, roll_deg])
        back = np.array([np.sin(yaw) * np.cos(pitch), np.sin(pitch), np.cos(yaw) * np.cos(pitch)])
        target = np.asarray(target_mm, dtype=np.float64)
        right = np.cross([0.0, 1.0, 0.0], back)
        right /= np.linalg.norm(right)
        up = np.cross(back, right)
        up = np.cos(roll) * up - np.sin(roll) * right
        return cls(int(width), int(height), float(f), float(f),
                   0.5 * (width - 1) + float(principal_offset_px[0]),
                   0.5 * (height - 1) + float(principal_offset_px[1]),
                   tuple(target + distance_mm * back), tuple(target), tuple(up),
                   tuple(float(c) for c in distortion))

    # ---------------------------------------------------------------- geometry
    def rotation(self) -> np.ndarray:
        """World -> camera rotation (3, 3): rows are the camera's x (right), y (down)
        and z (forward) axes in world coordinates."""
        fwd = np.asarray(self.target) - np.asarray(self.position)
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, self.up)
        right /= np.linalg.norm(right)
        down = np.cross(fwd, right)
        return np.stack([right, down, fwd])

    def project(self, points_mm: np.ndarray) -> np.ndarray:
        """Undistorted pixel coordinates (N, 2) ``(u, v)`` of world points (N, 3)."""
        pc = (np.asarray(points_mm, dtype=np.float64) - np.asarray(self.position)) @ self.rotation().T
        return np.column_stack([self.fx * pc[:, 0] / pc[:, 2] + self.cx,
                                self.fy * pc[:, 1] / pc[:, 2] + self.cy])

    def view_angle_deg(self) -> float:
        """The vertical field of view of the pinhole (deg)."""
        return float(np.degrees(2 * np.arctan(0.5 * self.height / self.fy)))

    def undistorted_coords(self) -> tuple[np.ndarray, np.ndarray]:
        """Where each pixel (H, W) of the distorted image samples the pinhole image:
        row and column coordinates (float64), for ``scipy.ndimage.map_coordinates``."""
        k1, k2, p1, p2, k3 = self.distortion
        v, u = np.mgrid[0:self.height, 0:self.width].astype(np.float64)
        x, y = (u - self.cx) / self.fx, (v - self.cy) / self.fy
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xu = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yu = y * radial + 2 * p2 * x * y + p1 * (r2 + 2 * y * y)
        return yu * self.fy + self.cy, xu * self.fx + self.cx

    def intrinsics(self) -> dict:
        """What a RealSense reports of its colour stream (for ``take.json``)."""
        return {"width": self.width, "height": self.height, "fx": self.fx, "fy": self.fy,
                "cx": self.cx, "cy": self.cy, "model": "inverse_brown_conrady",
                "coeffs": list(self.distortion)}


class LensDistortion:
    """Applies the camera's distortion to pinhole renders: each output pixel samples the
    pinhole image bilinearly (colour) or at the nearest pixel (labels), at the point
    :meth:`PinholeCamera.undistorted_coords` gives; the sample grid is computed once,
    and a call may ask for a box of the output only."""

    def __init__(self, camera: PinholeCamera):
        H, W = camera.height, camera.width
        self.shape = (H, W)
        rows, cols = camera.undistorted_coords()
        self.rows, self.cols = rows, cols
        r0, c0 = np.floor(rows), np.floor(cols)
        self.wr = (rows - r0).astype(np.float32)[..., None]
        self.wc = (cols - c0).astype(np.float32)[..., None]
        ri = [np.clip(r0 + k, 0, H - 1).astype(np.int64) for k in (0, 1)]
        ci = [np.clip(c0 + k, 0, W - 1).astype(np.int64) for k in (0, 1)]
        # flat indices of the four neighbours (faster to gather than 2D fancy indexing)
        self.idx = [[ri[a] * W + ci[b] for b in (0, 1)] for a in (0, 1)]
        self.near = (np.clip(np.rint(rows), 0, H - 1).astype(np.int64) * W
                     + np.clip(np.rint(cols), 0, W - 1).astype(np.int64))

    def box_reading(self, r0: int, r1: int, c0: int, c1: int, margin: int = 0):
        """The smallest output box (rows, cols; end exclusive) whose pixels sample the
        pinhole image's box [r0, r1) x [c0, c1), grown by ``margin`` and clipped."""
        inside = ((self.rows > r0 - 1) & (self.rows < r1) & (self.cols > c0 - 1) & (self.cols < c1))
        rr, cc = np.flatnonzero(inside.any(axis=1)), np.flatnonzero(inside.any(axis=0))
        H, W = self.shape
        if not len(rr):
            return 0, 0, 0, 0
        return (max(int(rr[0]) - margin, 0), min(int(rr[-1]) + 1 + margin, H),
                max(int(cc[0]) - margin, 0), min(int(cc[-1]) + 1 + margin, W))

    def image(self, img: np.ndarray, box=None) -> np.ndarray:
        """Colour (H, W, 3) float32 pinhole image -> the distorted image, or the
        ``box`` (r0, r1, c0, c1) of it."""
        r0, r1, c0, c1 = box or (0, self.shape[0], 0, self.shape[1])
        flat = img.reshape(-1, img.shape[-1])
        g = [[np.take(flat, self.idx[a][b][r0:r1, c0:c1], axis=0) for b in (0, 1)] for a in (0, 1)]
        wr, wc = self.wr[r0:r1, c0:c1], self.wc[r0:r1, c0:c1]
        top = g[0][0] + wc * (g[0][1] - g[0][0])
        bot = g[1][0] + wc * (g[1][1] - g[1][0])
        return top + wr * (bot - top)

    def labels(self, lab: np.ndarray, box=None) -> np.ndarray:
        """A label image (H, W), nearest neighbour (or the ``box`` of it)."""
        r0, r1, c0, c1 = box or (0, self.shape[0], 0, self.shape[1])
        return np.take(lab.reshape(-1), self.near[r0:r1, c0:c1])


class SensorNoise:
    """Photon shot and read noise on 8-bit-scale frames (float32, H x W x 3): Gaussian
    with variance ``shot_gain_dn * I + read_dn^2`` (DN^2), rounded to uint8.

    The unit normals come from a bank of four frames' worth of draws, read at a random
    offset per frame (a fresh draw per pixel costs more than the rest of a frame's
    processing): every frame's noise is white, and frames do not repeat one another."""

    def __init__(self, shape, read_dn: float, shot_gain_dn: float, rng: np.random.Generator):
        self.n = int(np.prod(shape))
        self.shape = tuple(shape)
        self.read2, self.gain = float(read_dn) ** 2, float(shot_gain_dn)
        self.rng = rng
        self.bank = rng.standard_normal(4 * self.n, dtype=np.float32)

    def sigma(self, img: np.ndarray) -> np.ndarray:
        """The noise's standard deviation (DN) of a noiseless image (float32)."""
        return np.sqrt(self.gain * np.clip(img, 0, None) + self.read2, dtype=np.float32)

    def apply(self, img: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """``img`` plus noise of ``sigma`` (same shape, float32) -> uint8."""
        off = int(self.rng.integers(0, 3 * self.n))
        out = self.bank[off:off + self.n].reshape(self.shape) * sigma
        out += img
        np.rint(out, out=out)
        np.clip(out, 0, 255, out=out)
        return out.astype(np.uint8)


class VideoWriter:
    """H.264 (``.mp4``) through PyAV, at ``fps`` with ``crf`` and ``pix_fmt``; x264's
    ``ultrafast`` preset (a camera's real-time encoder trades size for speed too)."""

    def __init__(self, path: str | Path, width: int, height: int, fps: float, crf: int = 20,
                 pix_fmt: str = "yuv444p", preset: str = "ultrafast"):
        from fractions import Fraction

        import av

        self.container = av.open(str(path), "w")
        self.stream = s = self.container.add_stream("libx264", rate=Fraction(fps).limit_denominator(1000))
        s.width, s.height, s.pix_fmt = int(width), int(height), pix_fmt
        # one encoder thread: a job has one core
        s.options = {"crf": str(int(crf)), "preset": preset, "threads": "1"}

    def write(self, rgb: np.ndarray) -> None:
        import av

        for pkt in self.stream.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb),
                                                                 format="rgb24")):
            self.container.mux(pkt)

    def close(self) -> None:
        for pkt in self.stream.encode():
            self.container.mux(pkt)
        self.container.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
