"""The pinhole camera of the perspective views, and a VTK camera set from it.

Conventions: world in mm (the FEA's x right, y up the finger, z out of its front face);
pixel coordinates as OpenCV's: u right, v down, the centre of pixel (row i, column j)
at (u, v) = (j, i).

Distortion is the inverse Brown-Conrady model a RealSense colour stream reports: for
a pixel of the (distorted) image, with normalised coordinates ``x, y`` and
``r^2 = x^2 + y^2``, the undistorted ray is
``x_u = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)`` (y alike), so
each output pixel samples the pinhole render at one point (no iteration). The
renderers here draw the pinhole image; the lab applies the distortion afterwards
(:class:`finray.emulator.camera.LensDistortion`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

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
    def looking_at(
        cls,
        target_mm,
        *,
        width: int,
        height: int,
        hfov_deg: float,
        distance_mm: float,
        yaw_deg: float = 0.0,
        pitch_deg: float = 0.0,
        roll_deg: float = 0.0,
        principal_offset_px=(0.0, 0.0),
        distortion=(0.0, 0.0, 0.0, 0.0, 0.0),
    ) -> "PinholeCamera":
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
        return cls(
            int(width),
            int(height),
            float(f),
            float(f),
            0.5 * (width - 1) + float(principal_offset_px[0]),
            0.5 * (height - 1) + float(principal_offset_px[1]),
            tuple(target + distance_mm * back),
            tuple(target),
            tuple(up),
            tuple(float(c) for c in distortion),
        )

    def scaled(self, factor: int) -> "PinholeCamera":
        """The same camera at ``factor`` x the resolution: the same rays, each pixel
        split into factor x factor (pixel centres: ``c' = (c + 0.5) factor - 0.5``)."""
        s = int(factor)
        return replace(
            self,
            width=self.width * s,
            height=self.height * s,
            fx=self.fx * s,
            fy=self.fy * s,
            cx=(self.cx + 0.5) * s - 0.5,
            cy=(self.cy + 0.5) * s - 0.5,
        )

    # ---------------------------------------------------------------- geometry
    def rotation(self) -> np.ndarray:
        """World -> camera rotation (3, 3): rows are the camera's x (right), y (down)
        and z (forward) axes in world coordinates."""
        fwd = np.asarray(self.target, dtype=np.float64) - np.asarray(self.position)
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, self.up)
        right /= np.linalg.norm(right)
        down = np.cross(fwd, right)
        return np.stack([right, down, fwd])

    def to_camera(self, points_mm: np.ndarray) -> np.ndarray:
        """World points (N, 3) in the camera's frame (N, 3) mm: x right, y down, z forward."""
        return (
            np.asarray(points_mm, dtype=np.float64) - np.asarray(self.position)
        ) @ self.rotation().T

    def project(self, points_mm: np.ndarray) -> np.ndarray:
        """Undistorted pixel coordinates (N, 2) ``(u, v)`` of world points (N, 3)."""
        pc = self.to_camera(points_mm)
        return np.column_stack(
            [self.fx * pc[:, 0] / pc[:, 2] + self.cx, self.fy * pc[:, 1] / pc[:, 2] + self.cy]
        )

    def undistorted_coords(self) -> tuple[np.ndarray, np.ndarray]:
        """Where each pixel (H, W) of the distorted image samples the pinhole image:
        row and column coordinates (float64), for ``scipy.ndimage.map_coordinates``."""
        k1, k2, p1, p2, k3 = self.distortion
        v, u = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64)
        x, y = (u - self.cx) / self.fx, (v - self.cy) / self.fy
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xu = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yu = y * radial + 2 * p2 * x * y + p1 * (r2 + 2 * y * y)
        return yu * self.fy + self.cy, xu * self.fx + self.cx

    def intrinsics(self) -> dict:
        """What a RealSense reports of its colour stream (for ``take.json``)."""
        return {
            "width": self.width,
            "height": self.height,
            "fx": self.fx,
            "fy": self.fy,
            "cx": self.cx,
            "cy": self.cy,
            "model": "inverse_brown_conrady",
            "coeffs": list(self.distortion),
        }


def set_vtk_camera(
    vtk_camera, pinhole: PinholeCamera, window=None, clipping: tuple[float, float] = (10.0, 1000.0)
) -> None:
    """Set a VTK camera so that a render window of the ``window`` box
    ``(u0, v0, width, height)`` (px; default: the whole frame) shows exactly the
    pinhole's pixels of that box: a world point lands on
    :meth:`PinholeCamera.project`'s pixel. The vertical view angle comes from ``fy``
    and the window's height (square pixels: VTK has one angle), the principal point
    from the window centre; ``clipping``: near and far planes (mm from the camera).
    """
    u0, v0, w, h = window or (0, 0, pinhole.width, pinhole.height)
    vtk_camera.SetPosition(*map(float, pinhole.position))
    vtk_camera.SetFocalPoint(*map(float, pinhole.target))
    vtk_camera.SetViewUp(*map(float, pinhole.up))
    vtk_camera.SetViewAngle(float(np.degrees(2 * np.arctan(0.5 * h / pinhole.fy))))
    # the principal point in the window (OpenCV pixel centres: display = pixel + 0.5)
    cx, cy = pinhole.cx - u0, pinhole.cy - v0
    vtk_camera.SetWindowCenter(-2.0 * (cx + 0.5 - 0.5 * w) / w, 2.0 * (cy + 0.5 - 0.5 * h) / h)
    vtk_camera.SetClippingRange(float(clipping[0]), float(clipping[1]))
