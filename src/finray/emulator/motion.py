"""The gripper's motion in a take: lower, hold, raise, repeated (the paper's section 5.3).

The push ``d(t)`` (mm) is the gripper's travel towards the object from its start
``gap_mm`` off the object (the FEA's object travel: the same number). Each ramp is a
minimum-jerk move (10 s^3 - 15 s^4 + 6 s^5 of the ramp's fraction s), as a position-
controlled linear axis makes it: zero speed and acceleration at both ends, mean speed
``speed_mm_s``. The finger is quasi-static in the FEA, so lowering and raising pass
through the same shapes; the force does not: a printed TPU finger relaxes in the hold,
reads lower on the way up and softer in a later cycle (``lab.as_built.viscoelastic``,
:mod:`finray.viscoelastic`, applied to the sensor's force by
:mod:`~finray.emulator.emulate`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..schema import schema_default


@dataclass(frozen=True)
class GripperMotion:
    """``push_mm`` travel per cycle at mean speed ``speed_mm_s``, held ``hold_s`` at
    the bottom; one cycle per start in ``starts_s`` (s, camera clock) in a take of
    ``duration_s``."""

    push_mm: float = schema_default("lab.motion.push_mm")
    speed_mm_s: float = schema_default("lab.motion.speed_mm_s")
    hold_s: float = schema_default("lab.motion.hold_s")
    starts_s: tuple[float, ...] = schema_default("lab.motion.starts_s")
    duration_s: float = schema_default("lab.motion.duration_s")

    @classmethod
    def from_config(cls, m: dict) -> "GripperMotion":
        return cls(
            push_mm=float(m["push_mm"]),
            speed_mm_s=float(m["speed_mm_s"]),
            hold_s=float(m["hold_s"]),
            starts_s=tuple(float(s) for s in m["starts_s"]),
            duration_s=float(m["duration_s"]),
        )

    @property
    def ramp_s(self) -> float:
        return self.push_mm / self.speed_mm_s

    def __post_init__(self):
        ends = [s + 2 * self.ramp_s + self.hold_s for s in self.starts_s]
        if any(b > a for a, b in zip(self.starts_s[1:], ends[:-1])) or (
            ends and (ends[-1] > self.duration_s or self.starts_s[0] < 0)
        ):
            raise ValueError(
                f"lab.motion: cycles at {list(self.starts_s)} s of "
                f"{2 * self.ramp_s + self.hold_s:g} s each overlap or leave the "
                f"{self.duration_s:g} s take"
            )

    def push(self, t) -> np.ndarray:
        """Travel d(t) (mm) at times ``t`` (s)."""
        t = np.asarray(t, dtype=np.float64)
        out = np.zeros_like(t)
        r = self.ramp_s
        for s in self.starts_s:
            up = np.clip((t - s) / r, 0.0, 1.0)
            down = np.clip((t - s - r - self.hold_s) / r, 0.0, 1.0)
            out += _min_jerk(up) - _min_jerk(down)
        return self.push_mm * out

    def speed(self, t) -> np.ndarray:
        """|d'(t)| (mm/s), by a central difference of :meth:`push`."""
        h = 1e-4
        return np.abs(self.push(np.asarray(t) + h) - self.push(np.asarray(t) - h)) / (2 * h)


def _min_jerk(s: np.ndarray) -> np.ndarray:
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
