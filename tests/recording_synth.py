"""Synthetic lab takes for the ingest tests: an orange Fin Ray-like finger (three
cavities, ribs between them) on a grey clamp, in front of a textured low-saturation
background, pushed at its front edge by a blue disc; its front edge deflects in
proportion to a known force profile, and the finger and clamp move down a little
(the gripper's motion). The sensor logs that force at its own rate on its own clock.

Known truth: the finger masks (after the disc and the clamp are drawn over it), the
force at each frame and the clock offset (camera time = sensor time + offset).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from skimage.draw import disk, polygon2mask

APEX = (27.0, 85.0)  # mm, x right and y up from the base's left edge
BASE_MM = 30.0
WALL_MM = 3.0
CAVITIES_MM = ((3.0, 18.0), (21.0, 38.0), (41.0, 56.0))
FINGER_RGB = np.array([225.0, 115.0, 30.0])
OBJECT_RGB = np.array([40.0, 80.0, 200.0])
CLAMP_RGB = np.array([105.0, 105.0, 108.0])


def profile(t: np.ndarray, starts, ramp: float, hold: float) -> np.ndarray:
    """Press-hold-release cycles in [0, 1] (smoothstep ramps), one per start (s)."""
    t = np.asarray(t, dtype=np.float64)
    out = np.zeros_like(t)
    for s in starts:
        up = np.clip((t - s) / ramp, 0, 1)
        down = np.clip((t - s - ramp - hold) / ramp, 0, 1)
        out += up * up * (3 - 2 * up) - down * down * (3 - 2 * down)
    return out


def _front(y):
    return APEX[0] * y / APEX[1]


def _back(y):
    return BASE_MM + (APEX[0] - BASE_MM) * y / APEX[1]


def _outline(y0, y1, inset, n=80):
    """Closed polygon (N, 2) in mm between heights y0 and y1, the edges moved in by inset."""
    ys = np.linspace(y0, y1, n)
    left = np.stack([_front(ys) + inset, ys], axis=1)
    right = np.stack([_back(ys) - inset, ys], axis=1)[::-1]
    return np.concatenate([left, right])


def _bend(pts, defl_mm, height_mm):
    """Move points in +x by the front edge's deflection, fading towards the back edge
    and away from the contact height."""
    x, y = pts[:, 0], pts[:, 1]
    rel = np.clip((x - _front(y)) / np.maximum(_back(y) - _front(y), 1e-6), 0, 1)
    dx = defl_mm * np.exp(-(((y - height_mm) / 18.0) ** 2)) * (1 - 0.8 * rel)
    return np.stack([x + dx, y], axis=1)


def background(shape, seed=0) -> np.ndarray:
    """Textured, low-saturation background (H, W, 3) float."""
    from scipy import ndimage as ndi

    rng = np.random.default_rng(seed)
    H, W = shape
    lum = ndi.gaussian_filter(rng.normal(0, 1, (H, W)), 6) * 60 + rng.normal(0, 4, (H, W))
    stripes = 12 * np.sin(np.arange(W) / 9.0)[None, :]
    base = np.array([150.0, 146.0, 136.0]) + (lum + stripes)[..., None]
    return base + rng.normal(0, 3, (H, W, 3))


def render_frame(bg, ppm, origin_px, defl_mm, drop_mm, height_mm=30.0, obj_r_mm=10.0):
    """One frame (H, W, 3) uint8 and the true finger mask (H, W) bool. ``origin_px``
    (col, row): the base's left edge at rest; ``drop_mm``: the gripper's downward move."""
    H, W = bg.shape[:2]
    c0, r0 = origin_px

    def to_rc(pts):  # mm -> (row, col) px
        return np.stack([r0 - (pts[:, 1] - drop_mm) * ppm, c0 + pts[:, 0] * ppm], axis=1)

    finger = polygon2mask((H, W), to_rc(_bend(_outline(0.0, APEX[1], 0.0), defl_mm, height_mm)))
    for y0, y1 in CAVITIES_MM:
        finger &= ~polygon2mask((H, W), to_rc(_bend(_outline(y0, y1, WALL_MM), defl_mm, height_mm)))
    clamp = polygon2mask((H, W), to_rc(np.array([[-6, -14], [36, -14], [36, 0], [-6, 0.0]])))
    cx_mm = _front(height_mm) - obj_r_mm + defl_mm * np.exp(0) * 1.0 + 0.3
    obj = np.zeros((H, W), bool)
    rr, cc = disk((r0 - height_mm * ppm, c0 + cx_mm * ppm), obj_r_mm * ppm, shape=(H, W))
    obj[rr, cc] = True
    shade = 1.0 - 0.15 * np.linspace(0, 1, H)[:, None, None]  # light from above
    img = np.clip(np.rint(bg), 0, 255).astype(np.uint8)
    for region, colour in (
        (finger, FINGER_RGB * shade),
        (clamp, CLAMP_RGB + 0.3 * (bg - 140)),
        (obj, OBJECT_RGB * shade),
    ):
        rows, cols = np.nonzero(region)
        img[rows, cols] = np.clip(np.rint(np.broadcast_to(colour, bg.shape)[rows, cols]), 0, 255)
    truth = finger & ~clamp & ~obj
    return img, truth


def write_take(
    folder,
    *,
    fps=30.0,
    duration_s=3.0,
    size=(480, 360),
    ppm=None,
    offset_s=-1000.047,
    sensor_hz=250.0,
    starts=(0.6,),
    ramp=0.7,
    hold=0.5,
    force_max_N=5.0,
    defl_max_mm=5.0,
    drop_max_mm=2.0,
    kind="mp4",
    noise_N=0.02,
    seed=0,
    take_json=None,
    force_fn=None,
    pix_fmt="yuv420p",
) -> dict:
    """Write a take (video ``take.mp4``/``take.avi`` or ``frames/`` + ``frames.csv``,
    ``forces.csv``, ``take.json``) into ``folder``; returns the truth: ``masks``
    (F, H, W) bool, ``t_s`` (camera), ``force_N`` (at each frame), ``offset_s``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    W, H = size
    ppm = ppm or H / 120.0  # the finger ~70 % of the height
    origin = (0.45 * W, 0.88 * H)
    bg = background((H, W), seed)
    n = int(round(duration_s * fps))
    t = np.arange(n) / fps
    prof = profile(t, starts, ramp, hold)
    frames, masks = [], []
    for k in range(n):
        img, m = render_frame(bg, ppm, origin, defl_max_mm * prof[k], drop_max_mm * prof[k])
        frames.append(img)
        masks.append(m)
    if kind == "frames":
        from PIL import Image

        (folder / "frames").mkdir(exist_ok=True)
        names = [f"f{k:05d}.png" for k in range(n)]
        for name, img in zip(names, frames):
            Image.fromarray(img).save(folder / "frames" / name)
        (folder / "frames.csv").write_text(
            "frame,t_s\n" + "".join(f"{a},{b:.6f}\n" for a, b in zip(names, t))
        )
    else:
        write_video(folder / f"take.{kind}", frames, fps, pix_fmt)
    # the sensor: its clock runs from before the video to after it
    rng = np.random.default_rng(seed + 1)
    ts = np.arange(-0.5 - offset_s, duration_s + 0.5 - offset_s, 1.0 / sensor_hz)
    f_true = force_max_N * profile(ts + offset_s, starts, ramp, hold)
    if force_fn is not None:
        f_true = force_fn(ts)
    fz = -f_true + 0.1 + rng.normal(0, noise_N, len(ts))
    fx = 0.05 * f_true + rng.normal(0, noise_N, len(ts))
    fy = rng.normal(0, noise_N, len(ts))
    (folder / "forces.csv").write_text(
        "t_s,fx_N,fy_N,fz_N\n"
        + "".join(f"{a:.6f},{b:.5f},{c:.5f},{d:.5f}\n" for a, b, c, d in zip(ts, fx, fy, fz))
    )
    meta = {
        "object": "cylinder",
        "contact_height_mm": 30.0,
        "push_axis": "-fz",
        "camera": {"px_per_mm": ppm},
        "emulated": "tests/recording_synth.py",
    }
    meta.update(take_json or {})
    (folder / "take.json").write_text(json.dumps(meta))
    return {
        "masks": np.stack(masks),
        "t_s": t,
        "force_N": force_max_N * prof + 0.0,
        "offset_s": offset_s,
        "frames": frames,
    }


def write_video(path, frames, fps, pix_fmt="yuv420p"):
    """H.264 (.mp4, crf 18, ``pix_fmt``) or MJPEG (.avi) with PyAV."""
    from fractions import Fraction

    import av

    path = Path(path)
    H, W = frames[0].shape[:2]
    with av.open(str(path), "w") as c:
        if path.suffix == ".avi":
            s = c.add_stream("mjpeg", rate=Fraction(fps).limit_denominator(1000))
            s.pix_fmt = "yuvj420p"
            s.bit_rate = 40_000_000  # a camera's MJPEG: high quality, every frame alike
        else:
            s = c.add_stream("libx264", rate=Fraction(fps).limit_denominator(1000))
            s.pix_fmt = pix_fmt
            s.options = {"crf": "18", "preset": "veryfast"}
        s.width, s.height = W, H
        for img in frames:
            for pkt in s.encode(av.VideoFrame.from_ndarray(img, format="rgb24")):
                c.mux(pkt)
        for pkt in s.encode():
            c.mux(pkt)
