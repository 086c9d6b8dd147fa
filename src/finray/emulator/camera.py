"""A colour camera: pinhole with lens distortion, exposure, sensor noise, lossy video.

The pinhole and its conventions (world mm, OpenCV pixels, the inverse Brown-Conrady
distortion) are :class:`finray.render.camera.PinholeCamera`'s, re-exported here; this
module adds what a real camera does to the pinhole image.
"""

from __future__ import annotations

import numpy as np

from ..render.camera import PinholeCamera

__all__ = ["LensDistortion", "PinholeCamera", "SensorNoise"]


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
        self.near = np.clip(np.rint(rows), 0, H - 1).astype(np.int64) * W + np.clip(
            np.rint(cols), 0, W - 1
        ).astype(np.int64)

    def box_reading(self, r0: int, r1: int, c0: int, c1: int, margin: int = 0):
        """The smallest output box (rows, cols; end exclusive) whose pixels sample the
        pinhole image's box [r0, r1) x [c0, c1), grown by ``margin`` and clipped."""
        inside = (self.rows > r0 - 1) & (self.rows < r1) & (self.cols > c0 - 1) & (self.cols < c1)
        rr, cc = np.flatnonzero(inside.any(axis=1)), np.flatnonzero(inside.any(axis=0))
        H, W = self.shape
        if not len(rr):
            return 0, 0, 0, 0
        return (
            max(int(rr[0]) - margin, 0),
            min(int(rr[-1]) + 1 + margin, H),
            max(int(cc[0]) - margin, 0),
            min(int(cc[-1]) + 1 + margin, W),
        )

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
        out = self.bank[off : off + self.n].reshape(self.shape) * sigma
        out += img
        np.rint(out, out=out)
        np.clip(out, 0, 255, out=out)
        return out.astype(np.uint8)
