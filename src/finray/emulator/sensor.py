"""The force sensor's log: a six-axis sensor (a Mini40 class) under the object.

The sensor's z axis points from the object towards the finger, so the push loads it in
compression: ``fz_N = -g (F_push) + b_z + noise`` (``push_axis: "-fz"``); its x axis is
the finger's length, ``fx_N = g F_along + b_x + noise``; y is out of the finger's plane
(no load). ``g = 1 + gain_error``, ``b`` the unzeroed offsets, ``noise`` white Gaussian
per axis. Its clock: ``sensor time = (camera time - offset) (1 + drift)``, where the
offset is the logger's start before the camera plus a latency, so that
``camera time = sensor time + offset_s`` holds to the drift (as
:mod:`finray.recording.sync` defines it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..schema import schema_default


@dataclass(frozen=True)
class ForceSensor:
    rate_hz: float = schema_default("lab.sensor.rate_hz")
    noise_N: tuple[float, float, float] = schema_default("lab.sensor.noise_N")
    bias_N: tuple[float, float, float] = schema_default("lab.sensor.bias_N")
    gain_error: float = schema_default("lab.sensor.gain_error")
    #: The logger's clock reads this much at the camera's time 0 (s), before latency.
    clock_start_s: float = schema_default("lab.sensor.clock_start_s")
    latency_s: tuple[float, float] = schema_default("lab.sensor.latency_s")
    drift_ppm: float = schema_default("lab.sensor.drift_ppm")
    #: Seconds the log runs before the camera's first frame and after its last.
    margin_s: float = schema_default("lab.sensor.margin_s")

    @classmethod
    def from_config(cls, s: dict) -> "ForceSensor":
        return cls(
            rate_hz=float(s["rate_hz"]),
            noise_N=tuple(map(float, s["noise_N"])),
            bias_N=tuple(map(float, s["bias_N"])),
            gain_error=float(s["gain_error"]),
            clock_start_s=float(s["clock_start_s"]),
            latency_s=tuple(map(float, s["latency_s"])),
            drift_ppm=float(s["drift_ppm"]),
            margin_s=float(s["margin_s"]),
        )

    def draw_offset(self, rng: np.random.Generator) -> float:
        """The take's clock offset (s): ``camera time = sensor time + offset``."""
        return -(self.clock_start_s + rng.uniform(*self.latency_s))

    def log(self, force_at, duration_s: float, offset_s: float, rng: np.random.Generator):
        """The log over the take: ``t_s`` (sensor clock) and ``fx_N, fy_N, fz_N``;
        ``force_at(t_camera)`` -> (F_push, F_along) in N, vectorised."""
        n = int(np.floor((duration_s + 2 * self.margin_s) * self.rate_hz)) + 1
        t_cam = -self.margin_s + np.arange(n) / self.rate_hz  # sample times, camera clock
        t_sensor = (t_cam - offset_s) * (1.0 + 1e-6 * self.drift_ppm)
        push, along = force_at(t_cam)
        g = 1.0 + self.gain_error
        noise = rng.normal(0.0, 1.0, (n, 3)) * np.asarray(self.noise_N)
        b = np.asarray(self.bias_N)
        return {
            "t_s": t_sensor,
            "fx_N": g * along + b[0] + noise[:, 0],
            "fy_N": b[1] + noise[:, 1],
            "fz_N": -g * push + b[2] + noise[:, 2],
        }


def write_forces_csv(path, log: dict) -> None:
    """``forces.csv`` as the logger writes it (``t_s`` to the microsecond, N to 0.1 mN)."""
    import pandas as pd

    df = pd.DataFrame(
        {"t_s": log["t_s"], "fx_N": log["fx_N"], "fy_N": log["fy_N"], "fz_N": log["fz_N"]}
    )
    df.to_csv(path, index=False, float_format="%.6f")
