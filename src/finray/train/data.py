"""The training data: the dataset stage's shards as network tensors, and the held-out
validation scenes."""

from __future__ import annotations

import numpy as np


#: Force components a model can predict -> the shards' per-frame arrays (N): along the
#: push (the FEA's x, the headline force) and across it (y, friction).
FORCE_COMPONENTS = {"fx": "fx_N", "fy": "fy_N"}


def load_split(
    shards,
    size: tuple[int, int],
    every: int = 1,
    forces: tuple[str, ...] = ("fx",),
    camera: bool = False,
) -> dict[str, np.ndarray]:
    """The frames of shards at one input size as network tensors (arrays): ``images``
    (N, 1, H, W) in [0, 1], ``stress`` (N, 1, H, W), ``mask`` (N, H, W) bool, ``fx_N``
    (N, 1), ``force_N`` (N, len(forces)): the components ``forces`` (``fx``, ``fy``) in N,
    ``contact_mm`` (N,) the contact height in mm (NaN without contact or label),
    and per-frame ``scene_id``, ``displacement_mm``; with ``camera`` also
    ``camera_images`` (N, 1, H, W) in [0, 1]: each frame seen by its randomised camera.
    ``every``: keep every ``every``-th frame of each shard (see
    :func:`finray.dataset.load_frames`)."""
    from ..dataset import load_frames

    a, table = load_frames(shards, size, every, require_stress=True, camera=camera)
    bad = [c for c in forces if c not in FORCE_COMPONENTS]
    if bad:
        raise ValueError(
            f"train.forces: unknown component(s) {bad}; known: {list(FORCE_COMPONENTS)}"
        )
    out = (
        {}
        if not camera
        else {"camera_images": a["camera_images"][:, None].astype(np.float32) / np.float32(255.0)}
    )
    return out | {
        "images": a["images"][:, None].astype(np.float32) / np.float32(255.0),
        "stress": a["stress"][:, None].astype(np.float32),
        "mask": a["mask"],
        "fx_N": a["fx_N"][:, None].astype(np.float32),
        "force_N": np.column_stack([a[FORCE_COMPONENTS[c]] for c in forces]).astype(np.float32),
        "contact_mm": a["contact_y_mm"].astype(np.float32),
        "scene_id": np.array(table["scene_id"].tolist()),
        "displacement_mm": table["displacement_mm"].to_numpy(),
    }


def frame_stiffness(scene_id, displacement_mm, fx_N) -> np.ndarray:
    """Each frame's local stiffness (N,): how fast ``|fx|`` (N) rises with the push's
    travel (mm) at that frame of its scene, in N/mm (``np.gradient`` along the scene's
    frames in travel order; NaN for a scene of one frame or no travel)."""
    _, inv = np.unique(np.asarray(scene_id), return_inverse=True)
    u = np.asarray(displacement_mm, dtype=float)
    f = np.abs(np.asarray(fx_N, dtype=float).reshape(len(u), -1)[:, 0])
    out = np.full(len(u), np.nan)
    order = np.lexsort((u, inv))  # by scene, then by travel
    for i in np.split(order, np.flatnonzero(np.diff(inv[order])) + 1):  # one slice per scene
        if len(i) > 1 and np.ptp(u[i]) > 0:
            with np.errstate(divide="ignore", invalid="ignore"):
                out[i] = np.gradient(f[i], u[i])
    out[~np.isfinite(out)] = np.nan  # frames at one travel (a held push): no slope
    return out


def shard_stress_ref(shards) -> float | None:
    """The stress maps' reference (MPa) the shards' renders used (``render.stress_ref_MPa``,
    from each shard's ``meta``); None where no shard records it. One line where they
    disagree (maps on two scales cannot train one network)."""
    import json

    refs = set()
    for path in shards:
        with np.load(path) as f:
            if "meta" in f.files:
                ref = (json.loads(str(f["meta"])).get("render") or {}).get("stress_ref_MPa")
                if ref is not None:
                    refs.add(float(ref))
    if len(refs) > 1:
        raise ValueError(
            f"the shards' stress maps use different references {sorted(refs)} MPa "
            "(render.stress_ref_MPa): render them alike"
        )
    return refs.pop() if refs else None


def validation_scenes(scene_ids, fraction: float, seed: int) -> set[str]:
    """Whole scenes held out for validation (frames of one scene are too alike to split)."""
    ids = sorted(set(scene_ids))
    rng = np.random.default_rng(seed)
    n_val = max(1, int(round(fraction * len(ids)))) if len(ids) > 1 else 0
    return set(rng.permutation(ids)[:n_val].tolist())


def scene_force_weights(scene_id, fx_N, floor_N: float) -> np.ndarray:
    """Per-frame weights (N,) that make a squared force error relative to its scene's
    largest |fx| (N, floored at ``floor_N``): ``1 / max(|fx|_scene, floor_N)**2``,
    scaled to mean 1 over the frames."""
    ids, inv = np.unique(np.asarray(scene_id), return_inverse=True)
    peak = np.zeros(len(ids))
    np.maximum.at(peak, inv, np.abs(np.asarray(fx_N, dtype=float).reshape(len(inv), -1)[:, 0]))
    w = 1.0 / np.maximum(peak, floor_N)[inv] ** 2
    return (w / w.mean()).astype(np.float32)
