"""The phases of a take: where a printed finger's time dependence shows.

A take lowers the gripper, holds, raises it, and again (:mod:`finray.emulator.motion`).
A printed finger's force relaxes in the hold, reads lower on the way up than down at
the same shape and softer in the second cycle (:mod:`finray.viscoelastic`), while the
image follows the push only: sim-to-real is reported per phase. The phases come from
the push per frame (``frames.csv`` with ``frame`` and ``push_mm``: the emulated rig's
``truth/frames.csv``, or a real rig's axis log in those columns); they label frames
for the report and never enter a fit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: the phases, in a take's order; ``second cycle``: every frame of the cycles after the first
PHASES = ("rest", "loading", "hold", "unloading", "second cycle")


def take_phases(push_mm, tol_mm: float = 1e-3) -> np.ndarray:
    """A phase of :data:`PHASES` per frame of a take's push (mm, in time order): rest at
    or below ``tol_mm``; in a cycle (a run of frames above it), the hold where the push
    is within ``tol_mm`` of the cycle's largest, loading before it, unloading after."""
    d = np.asarray(push_mm, dtype=np.float64)
    out = np.full(len(d), "rest", dtype=object)
    active = d > tol_mm
    edges = np.flatnonzero(np.diff(np.r_[0, active.astype(np.int8), 0]))
    for c, (a, b) in enumerate(zip(edges[::2], edges[1::2])):
        if c >= 1:
            out[a:b] = "second cycle"
            continue
        held = np.flatnonzero(d[a:b] >= d[a:b].max() - tol_mm) + a
        out[a : held[0]] = "loading"
        out[held[0] : held[-1] + 1] = "hold"
        out[held[-1] + 1 : b] = "unloading"
    return out


def shard_phases(shards, motions) -> np.ndarray | None:
    """The phase of every frame of ingested ``shards`` (in their order), from one motion
    table per shard (``frames.csv`` with ``frame`` and ``push_mm``); None without them."""
    import pandas as pd

    motions = list(motions or [])
    if not motions:
        return None
    if len(motions) != len(shards):
        raise ValueError(f"{len(motions)} motion tables for {len(shards)} takes")
    out = []
    for shard, motion in zip(shards, motions):
        table = pd.read_csv(motion)
        if not {"frame", "push_mm"} <= set(table.columns):
            raise ValueError(f"{motion}: needs the columns frame and push_mm")
        table = table.sort_values("frame")
        phase = dict(zip(table["frame"].to_numpy(), take_phases(table["push_mm"].to_numpy())))
        with np.load(Path(shard), allow_pickle=False) as f:
            frames = f["frame"]
        missing = [int(k) for k in frames if int(k) not in phase]
        if missing:
            raise ValueError(f"{motion}: no push for frames {missing[:5]} of {shard}")
        out.append(np.array([phase[int(k)] for k in frames], dtype=object))
    return np.concatenate(out) if out else None
