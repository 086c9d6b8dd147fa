"""Camera pitch as an image operation on the network input (for training augmentation).

The render stage's pitched camera is orthographic (:meth:`finray.render.params.RenderParams.project`):
a point ``(x, y, z)`` of the finger, extruded over ``z`` in ``[-e/2, e/2]`` (e: extrusion,
mm), appears at image height ``v = yc + (y - yc) cos(t) - z sin(t)``. The silhouette
at pitch ``t`` is therefore the front silhouette squeezed by ``cos(t)`` about ``yc``
and swept vertically by ``+-(e/2) sin(t)``: the side faces fill the cavities. Applied
to the soft (area-averaged) silhouette this reproduces the pitched renders closely
(see ``tests/dataset/test_pitch_augment.py``) at a tiny fraction of the cost of rendering
them in 3D, so that training can be augmented over a range of pitches. The stress target is
unchanged: it is the front view's, as in the pitch test set.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from ..schema import schema_default


def pitch_silhouette(
    x: torch.Tensor,
    pitch_deg: torch.Tensor,
    mm_per_px: float,
    centre_row: float,
    extrusion_mm: float = schema_default("finger.extrusion_mm"),
    step_px: float = 0.5,
) -> torch.Tensor:
    """Silhouettes ``x`` (B, C, H, W) in [0, 1] seen at camera pitches ``pitch_deg`` (B,).

    ``mm_per_px``: image-plane mm per pixel (vertical); ``centre_row``: the row (pixel
    centres at integers) of the camera's rotation axis ``yc``; ``step_px``: spacing of
    the vertical sweep samples (px).
    """
    b, _, h, w = x.shape
    t = torch.deg2rad(pitch_deg.to(x.dtype).reshape(b))
    cos, sin = torch.cos(t), torch.sin(t)
    half_sweep_px = 0.5 * extrusion_mm * sin / mm_per_px  # (B,)
    k = 2 * math.ceil(float(half_sweep_px.max()) / step_px) + 1 if b else 1
    # normalised coordinates (align_corners=False): y_n = (2 r + 1) / H - 1
    yc_n = (2.0 * centre_row + 1.0) / h - 1.0
    out = torch.zeros_like(x)
    for frac in torch.linspace(-1.0, 1.0, k).tolist():
        shift_n = 2.0 * frac * half_sweep_px / h  # (B,)
        # source height for output height v: yc + (v + shift - yc) / cos
        theta = torch.zeros(b, 2, 3, dtype=x.dtype)
        theta[:, 0, 0] = 1.0
        theta[:, 1, 1] = 1.0 / cos
        theta[:, 1, 2] = yc_n + (shift_n - yc_n) / cos
        grid = F.affine_grid(theta, list(x.shape), align_corners=False)
        out = torch.maximum(
            out, F.grid_sample(x, grid, mode="bilinear", padding_mode="zeros", align_corners=False)
        )
    return out
