"""Annotated frames for a person to watch: the predicted stress map drawn over the finger
in the camera's own pixels (log scale, a colour bar in MPa), the force as an arrow with
its magnitude (N), the calibrated force with its interval, the predicted contact height
(mm) as a mark on the finger's front edge; for a video, the annotated video (PyAV) and a
force-against-time plot.

The stress map covers the network's input window, which :meth:`finray.predict.Predictor.
crop_box` places on the camera frame (pixel edges, rows down): each camera pixel of the
finger's mask inside that window takes the map's value of the cell it falls in (nearest;
vectorised), coloured on a fixed log scale so that a video's frames compare.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numba as nb
import numpy as np

#: the stress maps' reference (MPa) where a model does not say (exports before it was
#: saved with the model: ``render.stress_ref_MPa``'s default, 1 kPa)
STRESS_REF_MPA = 1e-3
#: top of the colour scale (MPa)
STRESS_TOP_MPA = 1.0
#: top of the colour scale in the maps' unit at the default reference
STRESS_LOG_MAX = math.log10(1.0 + STRESS_TOP_MPA / STRESS_REF_MPA)
#: colour-bar ticks (MPa)
TICKS_MPA = (0.0, 0.01, 0.1, 1.0)
#: the arrow's scale: this many N span the input window's width
ARROW_N_PER_WINDOW = 5.0
BAR_PX = 96  # width of the colour-bar panel right of the frame
INVALID_RGB = (255, 40, 40)  # the border and text of a flagged frame


def stress_log(mpa, stress_ref_MPa: float = STRESS_REF_MPA):
    """MPa -> the maps' unit, log10(1 + sigma / stress_ref_MPa) (the model's
    reference: :attr:`finray.predict.Predictor.stress_ref_MPa`)."""
    return np.log10(1.0 + np.asarray(mpa, dtype=float) / stress_ref_MPa)


def stress_log_max(stress_ref_MPa: float = STRESS_REF_MPA) -> float:
    """The colour scale's top (:data:`STRESS_TOP_MPA`) in the maps' unit."""
    return float(stress_log(STRESS_TOP_MPA, stress_ref_MPa))


@functools.lru_cache(maxsize=4)
def _lut(name: str = "inferno") -> np.ndarray:
    from matplotlib import colormaps

    return (colormaps[name](np.linspace(0, 1, 256))[:, :3] * 255).astype(np.uint8)


def stress_cells(shape: tuple[int, int], box, map_shape: tuple[int, int]):
    """For a frame of ``shape`` (H, W) and the window ``box`` (col0, row0, col1, row1 in
    pixel edges): each row's and column's cell of a map of ``map_shape`` (h, w), and
    whether it falls inside the window: ``(i (H,), j (W,), in_rows (H,), in_cols (W,))``."""
    H, W = shape
    h, w = map_shape
    c0, r0, c1, r1 = box
    i = np.floor((np.arange(H) + 0.5 - r0) / (r1 - r0) * h).astype(np.int64)
    j = np.floor((np.arange(W) + 0.5 - c0) / (c1 - c0) * w).astype(np.int64)
    return np.clip(i, 0, h - 1), np.clip(j, 0, w - 1), (i >= 0) & (i < h), (j >= 0) & (j < w)


def overlay_stress(
    frame: np.ndarray,
    mask: np.ndarray,
    box,
    stress: np.ndarray,
    alpha: float = 0.65,
    vmax: float = STRESS_LOG_MAX,
) -> np.ndarray:
    """RGB (H, W, 3) uint8: ``frame`` (grey or RGB) with the log-stress map ``stress``
    (h, w) blended over the pixels of ``mask`` inside ``box``; pixels elsewhere keep the
    frame's values."""
    rgb = np.asarray(frame)
    rgb = np.repeat(rgb[..., None], 3, axis=2) if rgb.ndim == 2 else rgb[..., :3]
    return _overlay_into(rgb.astype(np.uint8, copy=True), mask, box, stress, alpha, vmax)


def _overlay_into(
    rgb: np.ndarray, mask: np.ndarray, box, stress: np.ndarray, alpha: float, vmax: float
) -> np.ndarray:
    """:func:`overlay_stress` in place on ``rgb`` (H, W, 3) uint8 (returned)."""
    i, j, in_r, in_c = stress_cells(rgb.shape[:2], box, stress.shape)
    rows, cols = np.flatnonzero(in_r), np.flatnonzero(in_c)
    if not len(rows) or not len(cols):
        return rgb
    sub = np.s_[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]  # the window's part of the frame
    # 8-bit fixed point (alpha in 256ths): the map's cells coloured once, each masked
    # pixel of the window blended with its cell's colour in one compiled pass (a third
    # of the time of numpy's passes over the whole window: docs/studies/realtime.md, the live loop)
    a = int(round(alpha * 256))
    cells = _lut()[np.clip(np.rint(stress / vmax * 255), 0, 255).astype(np.int64)]
    _blend_cells(
        rgb[sub],
        np.asarray(mask, bool)[sub],
        cells.astype(np.uint16) * a + 128,
        i[rows],
        j[cols],
        256 - a,
    )
    return rgb


@nb.njit(cache=True, nogil=True)
def _blend_cells(part, mask, colour, ci, cj, keep):  # pragma: no cover - compiled
    """``part`` (h, w, 3) uint8 in place, where ``mask``: ``(part * keep + colour of the
    pixel's cell) >> 8``, ``colour`` (map h, map w, 3) the cells' ``lut * alpha + 128``
    (uint16), ``ci`` (h,), ``cj`` (w,) each row's and column's cell. Integers throughout:
    the sum stays below 2^16."""
    for r in range(part.shape[0]):
        row = colour[ci[r]]
        for c in range(part.shape[1]):
            if mask[r, c]:
                cell = row[cj[c]]
                for k in range(3):
                    part[r, c, k] = (np.uint32(part[r, c, k]) * keep + cell[k]) >> 8


def peak_front_point(
    mask: np.ndarray, box, stress: np.ndarray, clamp_frac: float = 0.12
) -> tuple[int, int] | None:
    """(row, col) of the finger's front edge (its leftmost mask pixel) at the row of the
    map's largest stress above the clamp (the window's lowest ``clamp_frac``, where the
    base's stress peaks whatever the contact): where the arrow points (the contact)."""
    i, _, in_r, _ = stress_cells(mask.shape, box, stress.shape)
    row_peak = stress.max(axis=1)[i]  # each frame row's largest stress in the window
    in_r = in_r & (i < (1.0 - clamp_frac) * stress.shape[0])
    rows = np.flatnonzero(in_r & mask.any(axis=1))
    if not len(rows):
        return None
    r = int(rows[np.argmax(row_peak[rows])])
    return r, int(np.argmax(mask[r]))


def contact_point(
    mask: np.ndarray, box, crop_y_mm: tuple[float, float], contact_mm: float
) -> tuple[int, int] | None:
    """(row, col) of the finger's front edge (its leftmost mask pixel) at the height
    ``contact_mm`` (mm above the clamped base): the window ``box`` (pixel edges, rows
    down) spans ``crop_y_mm`` (its bottom edge at ``crop_y_mm[0]``), so a height is a row
    by linear interpolation. The nearest row of the mask where that row has none (above
    the tip); None outside the frame or without a mask."""
    c0, r0, c1, r1 = box
    y0, y1 = crop_y_mm
    if not math.isfinite(contact_mm):
        return None
    row = int(math.floor(r1 - (contact_mm - y0) / (y1 - y0) * (r1 - r0)))
    if not 0 <= row < mask.shape[0]:
        return None
    rows = np.flatnonzero(mask.any(axis=1))
    if not len(rows):
        return None
    r = int(rows[np.argmin(np.abs(rows - row))])
    return r, int(np.argmax(mask[r]))


CONTACT_RGB = (80, 255, 80)  # the contact mark's colour


def _draw_contact(canvas: np.ndarray, point: tuple[int, int], H: int) -> None:
    """A ring on the front edge at ``point`` (row, col) and a tick left of it."""
    r, c = point
    rad = max(4.0, H / 90)
    width = max(2, H // 240)
    pad = 3 * rad + width

    def mark(draw, dx, dy):
        draw.ellipse(
            [c - rad - dx, r - rad - dy, c + rad - dx, r + rad - dy],
            outline=CONTACT_RGB,
            width=width,
        )
        draw.line(
            [(c - 3 * rad - dx, r - dy), (c - rad - dx, r - dy)], fill=CONTACT_RGB, width=width
        )

    _draw_on(canvas, (c - pad, r - pad, c + pad + 1, r + pad + 1), mark)


def annotate_frame(
    frame: np.ndarray,
    mask: np.ndarray,
    box,
    stress: np.ndarray,
    forces: dict[str, float],
    calibrated: dict | None = None,
    label: str = "",
    crop_y_mm: tuple[float, float] | None = None,
    contact_min_force_N: float = 0.0,
    stress_ref_MPa: float = STRESS_REF_MPA,
    flags: list[str] | tuple = (),
) -> np.ndarray:
    """The annotated frame (H, W + BAR_PX, 3) uint8: the stress overlay
    (:func:`overlay_stress`), the force arrow at the front edge (``fx_N`` along the push,
    to the right; ``fy_N`` across it, up), its magnitude, the calibrated force and its
    interval (``calibrated``: ``force_N``, ``lo_N``, ``hi_N``, ``level``), ``label`` (e.g.
    the frame's name and time) and a colour bar in MPa. With ``contact_mm`` in ``forces``
    (mm above the clamped base) and ``|fx_N|`` above ``contact_min_force_N`` (N): a ring
    on the front edge at that height (:func:`contact_point`; ``crop_y_mm``, the window's
    heights in mm, places it) and the value. ``stress_ref_MPa``: the maps' reference (the
    model's; the colour bar is labelled in MPa through it). ``flags``: the frame's
    validity flags (:mod:`finray.validity`): a red border and a line naming them.
    Text and arrow are drawn on the patches they cover only, the colour bar is drawn
    once per frame height: a 1280x720 frame costs a few ms
    (``finray.benchmarks.realtime``)."""
    rgb = np.asarray(frame)
    H, W = rgb.shape[:2]
    canvas = np.empty((H, W + BAR_PX, 3), np.uint8)
    canvas[:, :W] = rgb[..., None] if rgb.ndim == 2 else rgb[..., :3]
    _overlay_into(canvas[:, :W], mask, box, stress, 0.65, stress_log_max(stress_ref_MPa))
    canvas[:, W:] = _bar_panel(H, float(stress_ref_MPa))
    fx, fy = forces.get("fx_N", 0.0), forces.get("fy_N", 0.0)
    mag = math.hypot(fx, fy)
    tip = peak_front_point(np.asarray(mask, bool), box, stress)
    if tip is not None and mag > 0:
        scale = (box[2] - box[0]) / ARROW_N_PER_WINDOW  # px per N
        r, c = tip
        ang = math.atan2(-fy, fx)
        head = max(6.0, H / 60)
        width = max(2, H // 240)
        lines = [[(c - scale * fx, r + scale * fy), (c, r)]]  # image rows grow down
        lines += [
            [(c, r), (c + head * math.cos(ang + da), r + head * math.sin(ang + da))]
            for da in (2.6, -2.6)
        ]
        pts = np.array([p for line in lines for p in line])

        def arrow(draw, dx, dy):
            for line in lines:
                draw.line([(x - dx, y - dy) for x, y in line], fill=(0, 255, 255), width=width)

        _draw_on(canvas, (*(pts.min(0) - width), *(pts.max(0) + width + 1)), arrow)
    text = [label] if label else []
    text.append(
        f"|F| {mag:.2f} N  (fx {fx:.2f} N, fy {fy:.2f} N)" if "fy_N" in forces else f"fx {fx:.2f} N"
    )
    contact = forces.get("contact_mm")
    if contact is not None and math.isfinite(contact) and abs(fx) > contact_min_force_N:
        if crop_y_mm is None:
            raise ValueError(
                "a contact height needs crop_y_mm (the window's heights, mm) to be drawn"
            )
        point = contact_point(np.asarray(mask, bool), box, crop_y_mm, contact)
        if point is not None:
            _draw_contact(canvas, point, H)
        text[-1] += f"  contact {contact:.1f} mm"
    if calibrated:
        text.append(
            f"calibrated {calibrated['force_N']:.2f} N, "
            f"{100 * calibrated['level']:.0f} % [{calibrated['lo_N']:.2f}, "
            f"{calibrated['hi_N']:.2f}] N"
        )
    if flags:
        b = max(3, H // 120)
        for sub in (np.s_[:b, :W], np.s_[-b:, :W], np.s_[:, :b], np.s_[:, W - b : W]):
            canvas[sub] = INVALID_RGB
        text.append("NOT VALID: " + ", ".join(flags))
    draw_text(canvas, (8, 6), "\n".join(text), max(12, H // 40))
    return canvas


TEXT_STROKE_PX = 2  # the black outline of the white text (readable on any frame)


@functools.lru_cache(maxsize=512)
def _glyph(ch: str, size: int, stroke: int) -> tuple[np.ndarray, np.ndarray, int, int, float]:
    """One character as Pillow draws it with an outline: the outline's and the fill's
    coverage (uint8, 0-255) on the patch that the outline covers (empty for a space),
    the patch's offset from the pen (x, y: px) and the pen's advance (px). Cached: a
    frame's text is a few dozen of them."""
    from PIL import Image, ImageDraw

    font = _font(size)
    pad = stroke + size // 4  # room for the outline and for glyphs that reach left
    adv = font.getlength(ch)
    img_w, img_h = int(math.ceil(adv)) + 2 * pad, _line_height(size, stroke) + 2 * pad
    outer, inner = Image.new("L", (img_w, img_h)), Image.new("L", (img_w, img_h))
    ImageDraw.Draw(outer).text(
        (pad, pad), ch, fill=255, font=font, stroke_width=stroke, stroke_fill=255
    )
    ImageDraw.Draw(inner).text((pad, pad), ch, fill=255, font=font)
    outer, inner = np.asarray(outer, np.uint8), np.asarray(inner, np.uint8)
    rows, cols = np.flatnonzero(outer.any(axis=1)), np.flatnonzero(outer.any(axis=0))
    if not len(rows):
        return outer[:0, :0], inner[:0, :0], 0, 0, adv
    # trimmed to the ink: the padding was most of each patch
    sub = np.s_[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
    return outer[sub].copy(), inner[sub].copy(), int(cols[0]) - pad, int(rows[0]) - pad, adv


@functools.lru_cache(maxsize=16)
def _line_height(size: int, stroke: int) -> int:
    """Pillow's multi-line spacing (its ``multiline_text`` with ``spacing=4``)."""
    from PIL import Image, ImageDraw

    box = ImageDraw.Draw(Image.new("L", (1, 1))).textbbox(
        (0, 0), "A", font=_font(size), stroke_width=stroke
    )
    return int(box[3]) + stroke + 4


def draw_text(
    canvas: np.ndarray, xy: tuple[int, int], text: str, size: int, stroke: int = TEXT_STROKE_PX
) -> None:
    """White text with a black outline on ``canvas`` (H, W, 3) uint8 in place, lines
    down from the pen ``xy`` (x, y: px, the first line's top). Composed from cached
    glyphs (:func:`_glyph`), not drawn anew: at 30 frames a second Pillow's rendering of
    a frame's two lines cost more than the stress overlay. Kerning is left out."""
    x0, y0 = xy
    step = _line_height(size, stroke)
    pieces, right, bottom = [], x0, y0
    for k, line in enumerate(text.split("\n")):
        pen = float(x0)
        for ch in line:
            outer, inner, dx, dy, adv = _glyph(ch, size, stroke)
            if outer.size:
                c, r = int(round(pen)) + dx, y0 + k * step + dy
                pieces.append((r, c, outer, inner))
                right, bottom = max(right, c + outer.shape[1]), max(bottom, r + outer.shape[0])
            pen += adv
    if not pieces:
        return
    top, left = min(p[0] for p in pieces), min(p[1] for p in pieces)
    outer_all = np.zeros((bottom - top, right - left), np.uint8)
    inner_all = np.zeros_like(outer_all)
    for r, c, outer, inner in pieces:
        sub = np.s_[r - top : r - top + outer.shape[0], c - left : c - left + outer.shape[1]]
        np.maximum(outer_all[sub], outer, out=outer_all[sub])
        np.maximum(inner_all[sub], inner, out=inner_all[sub])
    # clip the text's box to the canvas
    H, W = canvas.shape[:2]
    r0, c0, r1, c1 = max(top, 0), max(left, 0), min(bottom, H), min(right, W)
    if r1 <= r0 or c1 <= c0:
        return
    sub = np.s_[r0 - top : r1 - top, c0 - left : c1 - left]
    _compose_text(canvas[r0:r1, c0:c1], outer_all[sub], inner_all[sub])


@nb.njit(cache=True, nogil=True)
def _compose_text(part, outer, inner):  # pragma: no cover - compiled
    """White text with a black outline on ``part`` (h, w, 3) uint8 in place: black under
    the outline's coverage ``outer``, then white under the fill's ``inner`` (h, w; 0-255):
    ``part (1 - o)(1 - i) + 255 i`` in integers of 255^2, rounded; pixels that neither
    covers stay as they are (the formula gives them back exactly). One compiled pass:
    numpy's integer division over the text's box was most of the text's time."""
    for r in range(part.shape[0]):
        for c in range(part.shape[1]):
            o, i = np.int64(outer[r, c]), np.int64(inner[r, c])
            if o == 0 and i == 0:
                continue
            keep = (255 - o) * (255 - i)
            for k in range(3):
                part[r, c, k] = (part[r, c, k] * keep + i * 65025 + 32512) // 65025


def _draw_on(canvas: np.ndarray, box, draw_fn) -> None:
    """Draw on the patch ``box`` (x0, y0, x1, y1; clipped to the canvas) of ``canvas``
    only, in place: ``draw_fn(draw, x0, y0)`` gets a PIL ``ImageDraw`` of the patch and
    its offset (a whole-frame PIL round trip costs more than the drawing)."""
    from PIL import Image, ImageDraw

    x0, y0 = max(int(math.floor(box[0])), 0), max(int(math.floor(box[1])), 0)
    x1, y1 = (
        min(int(math.ceil(box[2])), canvas.shape[1]),
        min(int(math.ceil(box[3])), canvas.shape[0]),
    )
    if x1 <= x0 or y1 <= y0:
        return
    patch = Image.fromarray(canvas[y0:y1, x0:x1])
    draw_fn(ImageDraw.Draw(patch), x0, y0)
    canvas[y0:y1, x0:x1] = np.asarray(patch)


@functools.lru_cache(maxsize=4)
def _bar_panel(H: int, stress_ref_MPa: float = STRESS_REF_MPA) -> np.ndarray:
    """The colour-bar panel (H, BAR_PX, 3) uint8 right of a frame of height H, for maps
    of reference ``stress_ref_MPa``."""
    from PIL import Image, ImageDraw

    img = Image.new("RGB", (BAR_PX, H))
    _colour_bar(ImageDraw.Draw(img), img, 0, H, _font(max(12, H // 40)), stress_ref_MPa)
    panel = np.asarray(img)
    panel.flags.writeable = False
    return panel


@functools.lru_cache(maxsize=8)
def _font(size: int):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # pragma: no cover - Pillow < 10.1
        return ImageFont.load_default()


def bar_tick_rows(H: int, stress_ref_MPa: float = STRESS_REF_MPA) -> dict[float, float]:
    """Each tick's row (MPa -> row of the panel of a frame of height H): where the ramp
    has the colour that :func:`overlay_stress` gives a map value of that stress."""
    top, bottom = int(0.12 * H), int(0.88 * H)
    vmax = stress_log_max(stress_ref_MPa)
    return {
        t: bottom - float(stress_log(t, stress_ref_MPa)) / vmax * (bottom - top) for t in TICKS_MPA
    }


def _colour_bar(draw, img, x0: int, H: int, font, stress_ref_MPa: float = STRESS_REF_MPA) -> None:
    """The colour scale on the panel right of the frame: log stress, ticks in MPa."""
    from PIL import Image

    top, bottom = int(0.12 * H), int(0.88 * H)
    n = bottom - top
    ramp = _lut()[np.rint(np.linspace(255, 0, n)).astype(np.int64)]
    img.paste(Image.fromarray(np.repeat(ramp[:, None], 18, axis=1)), (x0 + 10, top))
    for t, y in bar_tick_rows(H, stress_ref_MPa).items():
        draw.line([(x0 + 28, y), (x0 + 34, y)], fill=(255, 255, 255))
        draw.text((x0 + 37, y), f"{t:g}", fill=(255, 255, 255), font=font, anchor="lm")
    draw.text((x0 + 8, top - 8), "stress\n(MPa)", fill=(255, 255, 255), font=font, anchor="ld")


def display_missing() -> str | None:
    """Why no window can open here (one line), or None where a display may exist."""
    import os
    import sys

    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        return "no display (DISPLAY and WAYLAND_DISPLAY unset)"
    return None


class Window:
    """Annotated frames in a window (Tk, through Pillow's ImageTk), for a person to watch
    a run: at most ``max_fps`` frames a second are drawn (a frame that comes sooner is
    not: the loop never waits for the screen), halved until they fit ``max_height_px``.
    Raises :class:`RuntimeError` (one line) where no window can open; closing the window
    stops the drawing, not the run."""

    def __init__(
        self, title: str = "finray predict", max_fps: float = 15.0, max_height_px: int = 900
    ):
        import time

        why = display_missing()
        if why:
            raise RuntimeError(why)
        try:
            import tkinter

            from PIL import ImageTk  # noqa: F401 - Pillow's Tk support, checked here

            self._root = tkinter.Tk()
        except Exception as exc:
            raise RuntimeError(f"cannot open a window ({str(exc).splitlines()[0]})") from None
        self._root.title(title)
        self._label = tkinter.Label(self._root)
        self._label.pack()
        self._root.protocol("WM_DELETE_WINDOW", self.close)
        self._min_dt, self._last, self._clock = 1.0 / max_fps, -float("inf"), time.perf_counter
        self.max_height_px, self.open, self.shown = max_height_px, True, 0

    def show(self, rgb: np.ndarray) -> None:
        from PIL import Image, ImageTk

        now = self._clock()
        if not self.open or now - self._last < self._min_dt:
            return
        self._last = now
        while rgb.shape[0] > self.max_height_px:
            rgb = rgb[::2, ::2]
        self._photo = ImageTk.PhotoImage(Image.fromarray(np.ascontiguousarray(rgb)))
        self._label.configure(image=self._photo)
        self._root.update()
        self.shown += 1

    def close(self) -> None:
        if self.open:
            self.open = False
            self._root.destroy()


def force_time_figure(rows: list[dict], path: str | Path, title: str = "") -> None:
    """Force against time (or frame) of a run's rows (``t_s`` where known): each force
    output, and the calibrated force with its interval where the rows have one; below
    it the contact height (mm) where the rows have one (``contact_mm``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.array([r.get("t_s") if r.get("t_s") is not None else np.nan for r in rows], float)
    x, xlabel = (t, "time (s)") if np.isfinite(t).all() else (np.arange(len(rows)), "frame")
    contact = bool(rows) and "contact_mm" in rows[0]
    fig, axes = plt.subplots(
        2 if contact else 1, 1, figsize=(7, 5 if contact else 3), sharex=True, squeeze=False
    )
    ax = axes[0, 0]
    for name in ("fx_N", "fy_N"):
        if rows and name in rows[0]:
            ax.plot(x, [r[name] for r in rows], lw=1, label=name.replace("_N", " (network)"))
    if rows and "force_N" in rows[0]:
        ax.fill_between(
            x,
            [r["lo_N"] for r in rows],
            [r["hi_N"] for r in rows],
            alpha=0.3,
            color="C2",
            label=f"{100 * rows[0]['level']:.0f} % interval",
        )
        ax.plot(x, [r["force_N"] for r in rows], color="C2", lw=1, label="calibrated")
    ax.set_ylabel("force (N)")
    ax.legend(fontsize=7)
    ax.set_title(title, fontsize=9)
    if contact:
        axes[1, 0].plot(x, [r["contact_mm"] for r in rows], color="C3", lw=1)
        axes[1, 0].set_ylabel("contact height (mm)")
    axes[-1, 0].set_xlabel(xlabel)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
