"""The paper-style example figure: input image, stress map, mask, every noise and
occlusion level, and the pitch series."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..render.params import RenderParams
from ..render.scene import load_render_index, read_render_frame
from .augment import apply_augment, augment_seed, sample_augment
from .imageops import area_resample
from .params import DatasetParams, size_key
from .shards import prepare_frame


def _crop_rgb(rgb, box):
    c0, r0, c1, r1 = (int(round(v)) for v in box)
    h, w = rgb.shape[:2]
    out = np.zeros((r1 - r0, c1 - c0, 3), dtype=rgb.dtype)
    rs, cs = slice(max(r0, 0), min(r1, h)), slice(max(c0, 0), min(c1, w))
    out[rs.start - r0 : rs.stop - r0, cs.start - c0 : cs.stop - c0] = rgb[rs, cs]
    return out


def example_figure(
    render_dir: str | Path,
    out_path: str | Path,
    *,
    frame: int = -1,
    pitch_dirs: dict[float, str | Path] | None = None,
    size: tuple[int, int] = (128, 64),
    params: DatasetParams | None = None,
    seed: int = 0,
) -> Path:
    """Write the example figure (PDF or PNG by ``out_path``'s suffix).

    Row 1: camera image, stress map, segmented mask, network input (``size``).
    Row 2: the input at each noise level; row 3: at each occlusion level (seeded
    with ``augment_seed(seed, scene_id, frame, level)``, so the figure is
    reproducible); row 4, if ``pitch_dirs`` (pitch -> render dir of the same
    scene) is given: the camera image of the same frame at each pitch.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    params = params or DatasetParams()
    index = load_render_index(render_dir)
    rp = RenderParams.from_config(index["params"])
    k = frame % index["n_frames"]
    rgb, maps = read_render_frame(render_dir, k, index)
    box = rp.box_px(params.crop_x_mm, params.crop_y_mm)
    arrays = prepare_frame(rgb, maps, box, params)
    key = size_key(size)
    inp = arrays[f"input_{key}"]
    seg = params.segment(rgb)
    stress_crop = area_resample(
        maps["stress"], box, (int(round(box[3] - box[1])), int(round(box[2] - box[0])))
    )
    scene_id = str(index.get("scene", {}).get("object", Path(render_dir).name))

    noise = list(params.noise)
    occl = list(params.occlusion)
    pitches = sorted((pitch_dirs or {}).items())
    ncols = max(4, len(noise), len(occl), len(pitches))
    nrows = 4 if pitches else 3
    fig, axes = plt.subplots(nrows, ncols, figsize=(1.6 * ncols, 3.0 * nrows), squeeze=False)
    for ax in axes.ravel():
        ax.set_axis_off()

    fr = index["frames"][k]
    axes[0, 0].imshow(_crop_rgb(rgb, box))
    axes[0, 0].set_title("camera image", fontsize=8)
    im = axes[0, 1].imshow(stress_crop, cmap="viridis", vmin=0)
    axes[0, 1].set_title("stress log10(1+σ/σref)", fontsize=8)
    fig.colorbar(im, ax=axes[0, 1], fraction=0.08, pad=0.02)
    axes[0, 2].imshow(_crop_rgb(np.repeat(seg[..., None], 3, axis=2).astype(np.uint8) * 255, box))
    axes[0, 2].set_title("mask (segmented)", fontsize=8)
    axes[0, 3].imshow(inp, cmap="gray", vmin=0, vmax=255)
    axes[0, 3].set_title(f"input {size[0]}x{size[1]}", fontsize=8)
    for j, level in enumerate(noise):
        p = sample_augment(
            augment_seed(seed, scene_id, k, "noise", level),
            size,
            noise=level,
            noise_levels=params.noise,
            occlusion_levels=params.occlusion,
        )
        axes[1, j].imshow(
            apply_augment(inp, p, params.occluder_value), cmap="gray", vmin=0, vmax=255
        )
        axes[1, j].set_title(f"noise {level}\n{params.noise[level]:.0%} of pixels", fontsize=8)
    for j, level in enumerate(occl):
        p = sample_augment(
            augment_seed(seed, scene_id, k, "occlusion", level),
            size,
            occlusion=level,
            noise_levels=params.noise,
            occlusion_levels=params.occlusion,
        )
        axes[2, j].imshow(
            apply_augment(inp, p, params.occluder_value), cmap="gray", vmin=0, vmax=255
        )
        lo, hi = params.occlusion[level]
        axes[2, j].set_title(f"occlusion {level}\ndisc {lo:.0%}-{hi:.0%} of width", fontsize=8)
    for j, (pitch, d) in enumerate(pitches):
        idx = load_render_index(d)
        prgb, _ = read_render_frame(d, k % idx["n_frames"], idx)
        axes[3, j].imshow(
            _crop_rgb(
                prgb,
                RenderParams.from_config(idx["params"]).box_px(params.crop_x_mm, params.crop_y_mm),
            )
        )
        axes[3, j].set_title(f"pitch {float(pitch):g}°", fontsize=8)
    fig.suptitle(
        f"{scene_id}: frame {k}, displacement {fr['displacement_mm']:.2f} mm, "
        f"fx {fr['fx_N']:.2f} N",
        fontsize=9,
    )
    fig.tight_layout()
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_path, dpi=150)
    plt.close(fig)
    return out_path
