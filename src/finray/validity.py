"""Whether a frame's prediction can be trusted: checks of each frame against what the
model was trained on, so that no frame is predicted silently where the model cannot know.

A frame gets a list of flags (none: valid):

- ``fills_frame``: the mask covers more than :attr:`Limits.max_mask_frac` of the frame
  (the background taken for the finger);
- ``off_frame``: more than :attr:`Limits.max_off_frame` of the finger's window (the
  base-anchored crop) lies outside the frame (the finger cut off by the frame's edge, or
  a mask that is not the finger);
- ``low_confidence``: the finger holds less than :attr:`Limits.min_confidence` of the
  frame's pixels of its colour or grey side (clutter of the finger's colour in view);
- ``grown``: the mask holds more than :attr:`Limits.max_growth` more pixels than in the
  first frames of the video or stream its colour was learned from (the finger at rest:
  a push hides part of it behind the object, so on 36 emulated takes it never grew
  past 1.003x; something of its colour touching it, e.g. a hand passing right behind
  it, merges into it: up to 1.24x); not checked where the colour was given or for
  separate images;
- ``shape``: the silhouette in the window is unlike the training's (its IoU with the
  training's mean silhouette below the training's lowest, or its filled share of the
  window outside the training's range, each less a margin);
- ``force_range``: a force outside the training's range (widened by
  :attr:`Limits.force_margin` of its span);
- ``contact_range``: for a model with the contact head, a contact height outside the
  trained heights (by more than :attr:`Limits.contact_margin_mm`), where ``|fx|`` is
  above the smallest force the height was trained on;
- ``near_base``: for a model with the contact head, a contact below the highest contact
  at which a training frame's force rose faster than :attr:`Limits.stiff_N_per_mm`
  per mm of the push's travel (where ``|fx|`` is above that smallest force): close to
  the clamped base the finger barely bends while the force climbs, so the image
  cannot tell the force (docs/studies/face.md, "Near the base").

The training's side (:func:`training_ranges`) is saved with the model
(``model.ts.json``'s ``trained``) by :func:`finray.train.export_torchscript`; a model
exported before has none, and only the frame's own checks run (the first four).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Each flag's meaning, in words (the end-of-run warning, the docs).
FLAGS = {
    "fills_frame": "the mask covers most of the frame (the background taken for the finger?)",
    "off_frame": "the finger's window reaches beyond the frame (cut off by its edge?)",
    "low_confidence": "much of the finger's colour lies outside the finger (clutter of its "
    "colour in view?)",
    "grown": "the mask grew past the first frames' (something of the finger's colour touching it?)",
    "shape": "the silhouette is unlike the training's",
    "force_range": "the force is outside the training's range",
    "contact_range": "the contact height is outside the trained heights",
    "near_base": "the contact is where the finger is too stiff near its base for the "
    "image to tell the force",
}
#: The silhouette grid (rows, columns) the shape is compared on.
SHAPE_GRID = (32, 16)


@dataclass(frozen=True)
class Limits:
    """Thresholds of the checks (fractions unless named with a unit)."""

    max_mask_frac: float = 0.5
    max_off_frame: float = 0.1
    min_confidence: float = 0.8
    max_growth: float = 0.05
    shape_margin: float = 0.15
    fill_margin: float = 0.05
    force_margin: float = 0.1
    contact_margin_mm: float = 2.0
    #: the training frames' local stiffness (N per mm of travel) above which the image is
    #: taken not to resolve the force (``near_base``); on the default training any value
    #: of 4-8 gives the same height, 3 also counts the ribs jamming higher up
    #: (docs/studies/face.md, "Near the base")
    stiff_N_per_mm: float = 4.0


def silhouette_grid(x: np.ndarray, grid: tuple[int, int] = SHAPE_GRID) -> np.ndarray:
    """Network inputs (N, [1,] H, W) in [0, 1] block-averaged to ``grid`` (N, gh, gw)
    (H and W multiples of the grid's)."""
    x = np.asarray(x, dtype=np.float32)
    x = x.reshape(len(x), *x.shape[-2:])
    gh, gw = grid
    n, H, W = x.shape
    if H % gh or W % gw:
        raise ValueError(f"an input of {H}x{W} does not block-average to {gh}x{gw}")
    return x.reshape(n, gh, H // gh, gw, W // gw).mean(axis=(2, 4))


def _iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU (N,) of masks (N, h, w) with one mask (h, w)."""
    inter = (a & b).sum(axis=(1, 2))
    union = (a | b).sum(axis=(1, 2))
    return inter / np.maximum(union, 1)


def training_ranges(
    images,
    force_N: np.ndarray,
    force_names,
    contact_mm: np.ndarray | None = None,
    contact_min_force_N: float = 0.0,
    chunk: int = 4096,
    stiffness_N_per_mm: np.ndarray | None = None,
    limits: Limits = Limits(),
) -> dict:
    """What the checks compare a frame with, from the training frames: ``images`` (N, 1,
    H, W) in [0, 1], or a list of such arrays (both views where the training saw both;
    read ``chunk`` frames at a time), ``force_N`` (N, F) named ``force_names``,
    ``contact_mm`` (N,) the contact heights (NaN where none; frames with ``|fx|`` above
    ``contact_min_force_N`` count); ``stiffness_N_per_mm`` (N,) each frame's local
    stiffness (:func:`finray.train.data.frame_stiffness`): ``stiff_below_mm``, the
    highest contact height of a frame stiffer than ``limits.stiff_N_per_mm``. JSON-ready."""
    parts = list(images) if isinstance(images, (list, tuple)) else [images]
    chunks = [p[i : i + chunk] for p in parts for i in range(0, len(p), chunk)]
    n = sum(len(c) for c in chunks)
    total = sum(silhouette_grid(c).sum(axis=0) for c in chunks)
    mean = total / n
    iou_min, fill_lo, fill_hi = 1.0, np.inf, -np.inf
    for c in chunks:
        iou_min = min(iou_min, float(_iou(silhouette_grid(c) >= 0.5, mean >= 0.5).min()))
        fill = np.asarray(c, np.float32).reshape(len(c), -1).mean(axis=1)
        fill_lo, fill_hi = min(fill_lo, float(fill.min())), max(fill_hi, float(fill.max()))
    f = np.asarray(force_N, dtype=np.float64).reshape(len(force_N), -1)
    out = {
        "n_frames": int(n),
        "fill": [fill_lo, fill_hi],
        "shape_iou_min": iou_min,
        "silhouette": np.round(mean, 3).tolist(),
        "force_N": {
            name: [float(f[:, k].min()), float(f[:, k].max())] for k, name in enumerate(force_names)
        },
    }
    if contact_mm is not None:
        c = np.asarray(contact_mm, dtype=np.float64).reshape(-1)
        has = np.isfinite(c) & (np.abs(f[: len(c), 0]) > contact_min_force_N)
        if has.any():
            out["contact_mm"] = [float(c[has].min()), float(c[has].max())]
        if stiffness_N_per_mm is not None:
            k = np.asarray(stiffness_N_per_mm, dtype=np.float64).reshape(-1)
            stiff = has & (np.nan_to_num(k, nan=0.0) > limits.stiff_N_per_mm)
            if stiff.any():
                out["stiff_below_mm"] = float(c[stiff].max())
    return out


def window_outside(box, shape: tuple[int, int]) -> float:
    """Fraction of the window ``box`` (col0, row0, col1, row1: pixel edges) outside a
    frame of ``shape`` (H, W)."""
    c0, r0, c1, r1 = box
    H, W = shape
    inside = max(0.0, min(c1, W) - max(c0, 0)) * max(0.0, min(r1, H) - max(r0, 0))
    area = (c1 - c0) * (r1 - r0)
    return 1.0 - inside / area if area > 0 else 1.0


def check_frame(
    mask_frac: float,
    outside: float,
    confidence: float,
    x: np.ndarray,
    forces: dict[str, float],
    trained: dict | None,
    contact_min_force_N: float = 0.0,
    limits: Limits = Limits(),
    growth: float | None = None,
) -> list[str]:
    """The flags (see the module's text) of one frame: ``mask_frac`` the mask's share of
    the frame, ``outside`` the window's share outside it (:func:`window_outside`),
    ``confidence`` the segmentation's (:class:`~finray.recording.finder.FingerFinder`),
    ``x`` the network input (1, 1, H, W) in [0, 1], ``forces`` the outputs by name
    (``fx_N``...; ``contact_mm`` for a model with the contact head); ``trained``:
    :func:`training_ranges` of the model (None: the frame's own checks only);
    ``growth``: the mask's pixels over the first frames' less 1 (None: not checked)."""
    flags = []
    if mask_frac > limits.max_mask_frac:
        flags.append("fills_frame")
    if outside > limits.max_off_frame:
        flags.append("off_frame")
    if confidence < limits.min_confidence:
        flags.append("low_confidence")
    if growth is not None and growth > limits.max_growth:
        flags.append("grown")
    if not trained:
        return flags
    mean = np.asarray(trained["silhouette"], np.float32)
    grid = silhouette_grid(x, mean.shape)
    iou = float(_iou(grid >= 0.5, mean >= 0.5)[0])
    fill = float(np.mean(x))
    lo, hi = trained["fill"]
    if (
        iou < trained["shape_iou_min"] - limits.shape_margin
        or not lo - limits.fill_margin <= fill <= hi + limits.fill_margin
    ):
        flags.append("shape")
    for name, (lo, hi) in trained.get("force_N", {}).items():
        v = forces.get(name)
        pad = limits.force_margin * (hi - lo)
        if v is not None and math.isfinite(v) and not lo - pad <= v <= hi + pad:
            flags.append("force_range")
            break
    c, span = forces.get("contact_mm"), trained.get("contact_mm")
    # the contact head's height counts where the frame is pushed (below that force it is a guess)
    if c is None or not math.isfinite(c) or abs(forces.get("fx_N", 0.0)) <= contact_min_force_N:
        return flags
    if span and not span[0] - limits.contact_margin_mm <= c <= span[1] + limits.contact_margin_mm:
        flags.append("contact_range")
    if near_base(c, forces.get("fx_N", 0.0), trained, contact_min_force_N)[0]:
        flags.append("near_base")
    return flags


def near_base(
    contact_mm, fx_N, trained: dict | None, contact_min_force_N: float = 0.0
) -> np.ndarray:
    """Which frames :func:`check_frame` flags ``near_base``, for arrays: the contact head's
    height ``contact_mm`` (mm) below the training's ``stiff_below_mm`` where ``|fx_N|`` is
    above ``contact_min_force_N`` (N). All False for a model without that height."""
    c = np.atleast_1d(np.asarray(contact_mm, dtype=np.float64))
    f = np.broadcast_to(np.abs(np.asarray(fx_N, dtype=np.float64)), c.shape)
    below = (trained or {}).get("stiff_below_mm")
    if below is None:
        return np.zeros(c.shape, bool)
    return np.isfinite(c) & (f > contact_min_force_N) & (c < below)


def flag_counts(rows: list[dict]) -> dict[str, int]:
    """How many rows carry each flag (``valid`` of :func:`finray.predict.predict_files`'s
    rows: ``ok`` or flags joined by ``+``)."""
    out: dict[str, int] = {}
    for r in rows:
        for f in r.get("valid", "ok").split("+"):
            if f != "ok":
                out[f] = out.get(f, 0) + 1
    return out
