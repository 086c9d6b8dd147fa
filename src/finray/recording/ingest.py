"""``finray ingest``: a lab take (video + sensor log) -> a dataset shard with sensor labels.

Per frame: colour-segment the finger (:mod:`finray.recording.finder`, as ``finray
predict`` does), cut the same
base-anchored window as :class:`~finray.predict.Predictor`
(:func:`~finray.dataset.imageops.base_anchored_box`), area-average it to each network
size. The image signal is the shift of the finger's left and right edges (mm, mean
over the window's rows; sub-pixel) from the first frame with a finger, in a window
anchored on each frame's base at the first frame's scale: the deformation, free of
the gripper's motion and of a pixel's jitter of the base width. Then the
sensor clock is aligned to the camera's (:mod:`finray.recording.sync`) and the push
force is averaged over each frame's interval.

Outputs in ``out_dir``: ``shard.npz`` (training format, no stress map:
``meta["has_stress"]`` false), ``frames.csv`` (every frame, with its status),
``sync.json`` (the offset and its uncertainty), ``ingest.json`` (summary, timings) and
``qa.png`` (frames with their masks; force against camera time with the image signal
overlaid after alignment) and, with ``write_masks``, ``masks.npz`` (every frame's
finger mask, to check the segmentation).
"""

from __future__ import annotations

import itertools
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..dataset.imageops import silhouette_input
from ..dataset.window import InputWindow
from ..dataset.params import scene_id, size_key
from ..dataset.shards import save_npz
from ..schema import schema_default
from .colour import ColourRange, learn_colour
from .finder import colour_finder
from .sync import align_clocks, force_at_frames
from .take import MIN_SAMPLES, TakeError, open_frames, read_forces, read_take_json

STATUSES = ("ok", "unreadable", "no_finger", "bad_base", "no_force")


@dataclass(frozen=True)
class IngestParams:
    """Crop and sizes (the dataset stage's and the finger's), segmentation and sync
    settings."""

    sizes: tuple[tuple[int, int], ...] = schema_default("dataset.sizes")
    #: The network's input window (the crop around the base, as the model's own: a
    #: calibration passes the model's; :class:`~finray.dataset.window.InputWindow`).
    window: InputWindow = field(default_factory=InputWindow)
    #: Subsampling (rows and columns) of the frame for finding the finger.
    stride: int = 4
    #: Frames the finger's colour is learned from when take.json gives none.
    learn_frames: int = 5
    min_object_frac: float = 1e-3
    #: Holes up to this fraction of the frame are filled (a compressed video's specks);
    #: the slits between ribs seen through the extrusion are larger and kept.
    max_hole_frac: float = 1e-5
    #: Largest relative deviation of a frame's base width (px) from the take's median.
    max_scale_dev: float = 0.1
    min_r: float = 0.5
    alpha: float = 0.05
    seed: int = 0
    qa_frames: int = 6
    #: Also write ``masks.npz``: every frame's full-resolution finger mask, bit-packed
    #: (``bits`` (F, H, ceil(W/8)) uint8, ``frame``, ``shape``; frames without one: empty).
    write_masks: bool = False


def check_take(take: str | Path):
    """A take folder's contents, checked without decoding its frames: ``(meta, t_force,
    force, frames)`` (take.json, the sensor's times and force along the push, the
    :class:`~finray.recording.take.FrameSource`), or a one-line :class:`TakeError`."""
    take = Path(take)
    if not take.is_dir():
        raise TakeError(f"{take} is not a take folder")
    meta = read_take_json(take / "take.json")
    t_force, force = read_forces(take / "forces.csv", meta["push_axis"])
    return meta, t_force, force, open_frames(take, meta)


def ingest(
    take: str | Path, out_dir: str | Path, params: IngestParams | None = None, log=print
) -> dict:
    """Ingest the take folder ``take`` into ``out_dir`` (see the module's text); returns
    the summary written to ``ingest.json``. Bad input raises :class:`TakeError`.

    The steps: read the take (:func:`check_take`), choose the finger's colour
    (:func:`_choose_colour`), segment and crop every frame (:func:`_measure_frames`),
    drop the frames without a usable finger (:func:`_frame_table`), align the clocks
    and label the frames with the force (:func:`_synchronise`), write the shard
    (:func:`_write_shard`), then the per-frame table, the QA figure and the report
    (:func:`_write_report`)."""
    t_wall, t_cpu = time.perf_counter(), time.process_time()
    p = params or IngestParams()
    take = Path(take)
    meta, t_force, force, src = check_take(take)
    log(
        f"{take.name}: {src.kind} {src.path.name}, {src.n_frames} frames at {src.rate_hz:.4g} FPS; "
        f"forces.csv: {len(t_force)} samples at {(len(t_force) - 1) / (t_force[-1] - t_force[0]):.4g} Hz"
    )
    frames = iter(src)
    head = _first_frames(frames, p.learn_frames)
    colour = _choose_colour(meta, head, p.stride, src)
    log(f"finger colour ({colour.source}): {colour.describe()}")
    # the one way the finger is found (finray predict's, with ingest's sizes)
    finder = colour_finder(colour, p.stride, p.min_object_frac, p.max_hole_frac)
    measured = _measure_frames(itertools.chain(head, frames), finder, src, p, log, t_wall)
    table, ok, had = _frame_table(measured.rows, src, colour, p)
    sync, labelled = _synchronise(table, ok, t_force, force, src, p, log)

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    scale = _scale(table.loc[ok, "base_px_per_mm"].to_numpy(), meta)
    _write_shard(
        out_dir / "shard.npz", take, meta, p, colour, sync, scale, table, labelled, had, measured
    )
    return _write_report(
        out_dir,
        take,
        src,
        p,
        colour,
        sync,
        scale,
        table,
        t_force,
        force,
        measured,
        (t_wall, t_cpu),
        log,
    )


def _first_frames(frames, n_readable: int) -> list:
    """The first ``(k, t, rgb)`` of the iterator ``frames`` up to its ``n_readable``-th
    readable frame (consumed from it): the frames a colour is learned from."""
    head = []
    for item in frames:
        head.append(item)
        if sum(rgb is not None for _, _, rgb in head) >= n_readable:
            break
    return head


def _choose_colour(meta: dict, head: list, stride: int, src) -> ColourRange:
    """The finger's colour: take.json's ``finger_colour``, else learned from the first
    frames ``head``; :class:`TakeError` when nothing there is coloured."""
    if "finger_colour" in meta:
        return ColourRange.from_take(meta["finger_colour"])
    colour = (
        learn_colour([rgb for _, _, rgb in head if rgb is not None], stride)
        if any(rgb is not None for _, _, rgb in head)
        else None
    )
    if colour is None:
        raise TakeError(
            f"no finger found: nothing coloured in the first frames of {src.path} "
            "(give finger_colour in take.json)"
        )
    return colour


@dataclass
class _Measured:
    """The pass over a take's frames: ``rows``, one per frame (its status and image
    signal: frames.csv); per frame with the finger, in order, its network ``inputs``
    (size key -> crops) and its crop box (``boxes``); ``thumbs`` (k, rgb, mask) of
    every few such frames for the QA figure; with ``write_masks``, ``packed`` (k,
    bit-packed mask, frame shape) of every readable frame."""

    rows: list
    inputs: dict
    boxes: list
    thumbs: list
    packed: list


class _ImageSignal:
    """A frame's deformation, measured in a window anchored on its base at the first
    measured frame's scale against that first frame: the shift of the finger's side
    edges (mm), the change of its silhouette (px) and its centroid (mm)."""

    def __init__(self, p: IngestParams):
        self.p = p
        self.big = max(p.sizes, key=lambda s: s[0] * s[1])
        self.crop_w_mm = p.window.crop_x_mm[1] - p.window.crop_x_mm[0]
        self.ref = self.ref_edges = self.ppm0 = None

    def measure(self, mask: np.ndarray, box) -> dict:
        """The frame's ``base_px_per_mm``, ``shape_change_px``, ``edge_shift_mm`` and
        ``centroid_dx_mm`` (before the take's first is subtracted); the first call
        sets the reference."""
        p, big, crop_w_mm = self.p, self.big, self.crop_w_mm
        ppm = (box[2] - box[0]) / crop_w_mm
        left, base_edge = box[0] - p.window.crop_x_mm[0] * ppm, box[3] + p.window.crop_y_mm[0] * ppm
        if self.ref is None:
            self.ppm0 = ppm
        ppm0 = self.ppm0
        # the image signal's window: anchored on this frame's base, at the first
        # frame's scale (a pixel more or less of base width must not read as bending)
        sig_box = (
            left + p.window.crop_x_mm[0] * ppm0,
            base_edge - p.window.crop_y_mm[1] * ppm0,
            left + p.window.crop_x_mm[1] * ppm0,
            base_edge - p.window.crop_y_mm[0] * ppm0,
        )
        x = silhouette_input(mask, sig_box, big).astype(np.float32)
        edges = side_edges(x)
        if self.ref is None:
            self.ref, self.ref_edges = x, edges
        both = np.isfinite(edges) & np.isfinite(self.ref_edges)
        edge_mm = (
            (
                float(np.abs(edges - self.ref_edges)[both].sum() / max(both.sum() / 2, 1))
                * crop_w_mm
                / big[1]
            )
            if both.any()
            else np.nan
        )
        w = x.sum(axis=0)
        cx_mm = (
            p.window.crop_x_mm[0]
            + crop_w_mm * float((w * (np.arange(big[1]) + 0.5)).sum() / max(w.sum(), 1e-9)) / big[1]
        )
        return {
            "base_px_per_mm": ppm,
            "shape_change_px": float(np.abs(x - self.ref).sum() / 255.0),
            "edge_shift_mm": edge_mm,
            "centroid_dx_mm": cx_mm,
        }


def _measure_frames(frames, finder, src, p: IngestParams, log, t_wall: float) -> _Measured:
    """Segment each ``(k, t, rgb)`` of ``frames`` with ``finder``, crop it as the
    predictor does (:func:`~finray.dataset.imageops.base_anchored_box`) to each size and
    measure its image signal; logs the progress every tenth of the take."""
    out = _Measured([], {size_key(s): [] for s in p.sizes}, [], [], [])
    signal = _ImageSignal(p)
    n_total = max(src.n_frames, 1)
    thumb_every = max(1, n_total // 60)
    next_report = 0.1
    for k, t, rgb in frames:
        row = {
            "frame": k,
            "t_s": t,
            "status": "ok",
            "mask_area_px": 0,
            "base_px_per_mm": np.nan,
            "shape_change_px": np.nan,
            "edge_shift_mm": np.nan,
            "centroid_dx_mm": np.nan,
        }
        mask = None
        if rgb is None:
            row["status"] = "unreadable"
        else:
            mask, _ = finder.find(rgb)
            if mask is None:
                row["status"] = "no_finger"
        if p.write_masks and rgb is not None:
            bits = np.packbits(mask if mask is not None else np.zeros(rgb.shape[:2], bool), axis=-1)
            out.packed.append((k, bits, rgb.shape[:2]))
        if mask is not None:
            box = p.window.box(mask)
            for s, x in p.window.inputs(mask, p.sizes, box).items():
                out.inputs[size_key(s)].append(x)
            row.update(mask_area_px=int(mask.sum()), **signal.measure(mask, box))
            out.boxes.append(box)
            if k % thumb_every == 0:
                out.thumbs.append((k, *_thumb(rgb, mask)))
        out.rows.append(row)
        if (k + 1) / n_total >= next_report:
            n_ok = sum(r["status"] == "ok" for r in out.rows)
            log(
                f"  frame {k + 1}/{src.n_frames}: {n_ok} with the finger "
                f"({time.perf_counter() - t_wall:.1f} s)"
            )
            next_report += 0.1
    return out


def _frame_table(rows: list, src, colour: ColourRange, p: IngestParams):
    """The frames' table, frames with a mis-segmented base marked ``bad_base``, and the
    centroid taken relative to the first usable frame's: ``(table, ok, had)``, ``ok``
    the usable frames, ``had`` those the finder found (one crop each).
    :class:`TakeError` when too few frames are usable."""
    import pandas as pd

    table = pd.DataFrame(rows)
    ok = (table["status"] == "ok").to_numpy()
    if not ok.any():
        raise TakeError(
            f"no finger found in any of the {len(table)} frames of {src.path} ({colour.describe()})"
        )
    if ok.sum() < MIN_SAMPLES:
        raise TakeError(
            f"{src.path}: too few frames with the finger ({int(ok.sum())} of "
            f"{len(table)}; at least {MIN_SAMPLES})"
        )
    # the base's width is the finger's: a frame whose measured scale is off the take's
    # median by more than ``max_scale_dev`` had its base mis-segmented (its crop would be wrong)
    had = ok.copy()
    ppm_all = table["base_px_per_mm"].to_numpy()
    bad_base = ok & (np.abs(ppm_all / np.median(ppm_all[ok]) - 1) > p.max_scale_dev)
    table.loc[bad_base, "status"] = "bad_base"
    ok = (table["status"] == "ok").to_numpy()
    if ok.sum() < MIN_SAMPLES:
        raise TakeError(
            f"{src.path}: too few frames with the finger's base found ({int(ok.sum())} "
            f"of {len(table)}; at least {MIN_SAMPLES})"
        )
    if table["centroid_dx_mm"].notna().any():
        table["centroid_dx_mm"] -= table.loc[ok, "centroid_dx_mm"].iloc[0]
    return table, ok, had


def _synchronise(table, ok, t_force, force, src, p: IngestParams, log):
    """Align the sensor's clock to the camera's on the usable frames' edge shift
    (:func:`~finray.recording.sync.align_clocks`) and label every frame with the force
    over its interval (``table["force_N"]``; frames outside the log marked
    ``no_force``): ``(sync, labelled)``, ``labelled`` the frames that go to the shard."""
    t_frames = table["t_s"].to_numpy(dtype=np.float64)
    frame_dt = float(np.median(np.diff(t_frames))) if len(t_frames) > 1 else 1.0 / src.rate_hz
    sync = align_clocks(
        t_frames[ok],
        table.loc[ok, "edge_shift_mm"].to_numpy(),
        t_force,
        force,
        frame_dt,
        min_r=p.min_r,
        alpha=p.alpha,
        seed=p.seed,
    )
    log(
        f"clock offset {sync['offset_s']:+.4f} s +- {sync['uncertainty_s']:.4f} s "
        f"(camera = sensor + offset; r {sync['pearson_r']:.3f}, p {sync['p_value']:.3f})"
    )
    table["force_N"] = force_at_frames(t_frames, t_force, force, sync["offset_s"], frame_dt)
    no_force = ok & ~np.isfinite(table["force_N"].to_numpy())
    table.loc[no_force, "status"] = "no_force"
    return sync, ok & ~no_force


def _scale(px_mm: np.ndarray, meta: dict) -> dict:
    """The measured scale (px/mm of the usable frames' bases ``px_mm``), and its ratio
    to take.json's, when given."""
    scale = {
        "measured_px_per_mm_median": float(np.median(px_mm)),
        "measured_px_per_mm_spread": float(np.percentile(px_mm, 95) - np.percentile(px_mm, 5)),
    }
    if "px_per_mm" in meta["camera"]:
        scale["given_px_per_mm"] = float(meta["camera"]["px_per_mm"])
        scale["ratio_measured_to_given"] = (
            scale["measured_px_per_mm_median"] / scale["given_px_per_mm"]
        )
    return scale


def _write_shard(
    path, take: Path, meta, p: IngestParams, colour, sync, scale, table, labelled, had, measured
) -> None:
    """The shard (training format, no stress map) of the ``labelled`` frames: their
    crops, masks, times, force labels and crop boxes, and the take's meta."""
    keep = labelled[had]  # the kept crops (one per frame with a finger) that go to the shard
    scene = {
        "object": meta["object"],
        "material": "lab",
        "height_mm": float(meta["contact_height_mm"]),
        "split": "lab",
        "splits": ["lab"],
        "pitch_deg": 0.0,
    }
    scene["scene_id"] = f"{scene_id(scene)}_{take.name}"
    shard_meta = {
        "scene": scene,
        "source": "recording",
        "take": str(take),
        "has_stress": False,
        "stress": "absent: a lab recording has no stress map",
        "force_label": f"the sensor's push force ({meta['push_axis']}, N), mean over each "
        "frame's interval after clock alignment, not tared",
        "sizes": [list(s) for s in p.sizes],
        "crop_box_px": "per frame: crop_box_px array",
        "dataset": {
            "sizes": [list(s) for s in p.sizes],
            "crop_x_mm": list(p.window.crop_x_mm),
            "crop_y_mm": list(p.window.crop_y_mm),
        },
        "base_width_mm": p.window.base_width_mm,
        "camera": meta["camera"],
        "colour": colour.to_dict(),
        "sync": sync,
        "n_frames": int(labelled.sum()),
        "n_frames_take": len(table),
        "scale": scale,
        "support_iou_min": None,
    }
    arrays = {}
    for key, v in measured.inputs.items():
        arrays[f"input_{key}"] = np.stack(v)[keep]
        # covered at least half (the soft value x255 rounds to 128 or more)
        arrays[f"mask_{key}"] = (arrays[f"input_{key}"] >= 128).astype(np.uint8)
    sel = table[labelled]
    n = len(sel)
    arrays.update(
        frame=sel["frame"].to_numpy(dtype=np.int32),
        t_s=sel["t_s"].to_numpy(dtype=np.float64),
        fea_frame=np.full(n, np.nan),
        displacement_mm=np.full(n, np.nan),
        fx_N=sel["force_N"].to_numpy(dtype=np.float64),
        fy_N=np.full(n, np.nan),
        contact_y_mm=np.full(n, np.nan),  # the contact height: not measured on a rig
        crop_box_px=np.asarray(measured.boxes, dtype=np.float64)[keep],
        meta=np.array(json.dumps(shard_meta)),
    )
    save_npz(path, arrays)


def _write_report(
    out_dir: Path,
    take,
    src,
    p,
    colour,
    sync,
    scale,
    table,
    t_force,
    force,
    measured,
    clocks,
    log,
) -> dict:
    """``frames.csv``, ``sync.json``, ``masks.npz`` (with ``write_masks``), ``qa.png`` and
    ``ingest.json`` (the summary, returned; ``clocks``: the wall and CPU clocks at the
    start); logs the lost frames and the counts."""
    t_wall, t_cpu = clocks
    cols = [
        "frame",
        "t_s",
        "status",
        "force_N",
        "mask_area_px",
        "base_px_per_mm",
        "edge_shift_mm",
        "shape_change_px",
        "centroid_dx_mm",
    ]
    table[cols].to_csv(out_dir / "frames.csv", index=False, float_format="%.6g")
    (out_dir / "sync.json").write_text(json.dumps(sync, indent=1))
    if p.write_masks:
        packed = measured.packed
        np.savez_compressed(
            out_dir / "masks.npz",
            bits=np.stack([b for _, b, _ in packed]),
            frame=np.array([k for k, _, _ in packed], np.int32),
            shape=np.array([len(packed), *packed[0][2]]),
        )
    qa_figure(
        out_dir / "qa.png", table, t_force, force, sync, measured.thumbs, p.qa_frames, take.name
    )
    counts = {s: int((table["status"] == s).sum()) for s in STATUSES}
    summary = {
        "take": str(take),
        "video": str(src.path),
        "kind": src.kind,
        "frame_rate_hz": src.rate_hz,
        "frames": counts,
        "colour": colour.to_dict(),
        "sync": sync,
        "scale": scale,
        "lost": src.lost,
        "wall_s": time.perf_counter() - t_wall,
        "cpu_s": time.process_time() - t_cpu,
    }
    (out_dir / "ingest.json").write_text(json.dumps(summary, indent=1))
    for why in src.lost[:5]:
        log(f"lost: {why}")
    if len(src.lost) > 5:
        log(f"lost: {len(src.lost) - 5} more (ingest.json)")
    log(
        f"{counts['ok']} frames -> {out_dir / 'shard.npz'} ({counts['no_finger']} without the "
        f"finger, {counts['bad_base']} with a mis-segmented base, {counts['unreadable']} unreadable, "
        f"{counts['no_force']} outside the force log); "
        f"{summary['wall_s']:.1f} s"
    )
    return summary


def side_edges(x: np.ndarray) -> np.ndarray:
    """Left and right edges (2, H) of a soft silhouette (H, W) uint8, in columns from
    the left (sub-pixel: where a row first crosses half coverage, interpolated); NaN
    for rows without the finger."""
    out = np.full((2, x.shape[0]), np.nan)
    rows = np.arange(x.shape[0])
    for side, a in enumerate((x, x[:, ::-1])):
        a = a.astype(np.float64)
        on = a >= 127.5
        j = on.argmax(axis=1)
        has = on[rows, j]
        prev = a[rows, np.maximum(j - 1, 0)]
        frac = np.where(j > 0, (a[rows, j] - 127.5) / np.maximum(a[rows, j] - prev, 1e-9), 0.0)
        e = j - np.clip(frac, 0, 1)
        out[side, has] = e[has] if side == 0 else (x.shape[1] - e)[has]
    return out


def _thumb(rgb: np.ndarray, mask: np.ndarray, pad: float = 0.15):
    """The finger's box (plus ``pad`` of its size) of the frame and its mask."""
    r = np.flatnonzero(mask.any(axis=1))
    c = np.flatnonzero(mask.any(axis=0))
    dr, dc = int(pad * (r[-1] - r[0] + 1)), int(pad * (c[-1] - c[0] + 1))
    r0, r1 = max(r[0] - dr, 0), min(r[-1] + 1 + dr, rgb.shape[0])
    c0, c1 = max(c[0] - dc, 0), min(c[-1] + 1 + dc, rgb.shape[1])
    return rgb[r0:r1, c0:c1].copy(), mask[r0:r1, c0:c1].copy()


def qa_figure(path, table, t_force, force, sync, thumbs, n_show: int, title: str) -> None:
    """A strip of frames with their masks (outlined), and force against camera time:
    the sensor's log shifted by the offset, the per-frame labels, and the image
    signal fitted (least squares, a x signal + b) onto the force."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from skimage.segmentation import find_boundaries

    ok = (table["status"] == "ok").to_numpy()
    sig = table["edge_shift_mm"].to_numpy()
    if thumbs:
        pick = np.unique(
            np.linspace(0, len(thumbs) - 1, min(n_show, len(thumbs))).round().astype(int)
        )
        strongest = int(np.argmax([sig[k] if np.isfinite(sig[k]) else -1 for k, _, _ in thumbs]))
        if strongest not in pick:
            pick[np.argmin(np.abs(pick - strongest))] = strongest
        pick = np.unique(pick)
    else:
        pick = []
    fig = plt.figure(figsize=(max(8, 1.6 * len(pick)), 6.5))
    gs = fig.add_gridspec(2, max(len(pick), 1), height_ratios=[1.2, 1])
    for j, i in enumerate(pick):
        k, img, m = thumbs[i]
        over = img.copy()
        over[m] = (0.5 * over[m] + 0.5 * np.array([0, 255, 0])).astype(np.uint8)
        over[find_boundaries(m, mode="inner")] = (255, 0, 255)
        ax = fig.add_subplot(gs[0, j])
        ax.imshow(over)
        ax.set_title(f"frame {k}\nt {table['t_s'].iloc[k]:.2f} s", fontsize=8)
        ax.axis("off")
    ax = fig.add_subplot(gs[1, :])
    ax.plot(t_force + sync["offset_s"], force, color="0.6", lw=0.6, label="sensor (aligned)")
    lab = ok & np.isfinite(table["force_N"].to_numpy())
    t = table["t_s"].to_numpy()
    ax.plot(
        t[lab],
        table["force_N"].to_numpy()[lab],
        ".",
        ms=3,
        color="C0",
        label="force label per frame",
    )
    if lab.sum() >= 2:
        a, b = np.polyfit(sig[lab], table["force_N"].to_numpy()[lab], 1)
        ax.plot(
            t[ok], a * sig[ok] + b, color="C3", lw=1.2, label="image signal (edge shift, fitted)"
        )
    ax.set_xlim(t.min() - 0.05 * np.ptp(t), t.max() + 0.05 * np.ptp(t))
    ax.set_xlabel("camera time (s)")
    ax.set_ylabel("push force (N)")
    ax.set_title(
        f"{title}: offset {sync['offset_s']:+.4f} s +- {sync['uncertainty_s']:.4f} s, "
        f"r {sync['pearson_r']:.3f}",
        fontsize=9,
    )
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
