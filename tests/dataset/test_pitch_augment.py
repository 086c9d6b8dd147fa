"""Pitch as an image operation: the orthographic view of an extruded box, analytically."""

import numpy as np
import pytest
import torch

from finray.dataset.pitch import pitch_silhouette

MM_PER_PX = 0.25
H, W = 400, 80  # 100 mm x 20 mm image
CENTRE_ROW = 199.5  # the axis at the image's middle (50 mm)


def box_image(top_mm: float, bottom_mm: float) -> torch.Tensor:
    """A box spanning image heights [bottom_mm, top_mm] (height measured upwards)."""
    v = 100.0 - (np.arange(H) + 0.5) * MM_PER_PX  # height of each row centre (mm)
    img = ((v >= bottom_mm) & (v <= top_mm)).astype(np.float32)[:, None] * np.ones(W, np.float32)
    img[:, :10] = 0
    return torch.from_numpy(img)[None, None]


def extent_mm(img: torch.Tensor) -> tuple[float, float]:
    rows = np.flatnonzero(img[0, 0, :, 40].numpy() >= 0.5)
    top = 100.0 - rows[0] * MM_PER_PX
    bottom = 100.0 - (rows[-1] + 1) * MM_PER_PX
    return bottom, top


@pytest.mark.parametrize("pitch", [0.0, 5.0, 10.0, 20.0, 30.0])
def test_box_extent_matches_orthographic_projection(pitch):
    """v = yc + (y - yc) cos t -/+ (e/2) sin t: the box's image spans exactly that."""
    x = box_image(80.0, 20.0)
    out = pitch_silhouette(x, torch.tensor([pitch]), MM_PER_PX, CENTRE_ROW, extrusion_mm=20.0)
    t = np.radians(pitch)
    yc = 50.0
    top = yc + (80.0 - yc) * np.cos(t) + 10.0 * np.sin(t)
    bottom = yc + (20.0 - yc) * np.cos(t) - 10.0 * np.sin(t)
    b, tp = extent_mm(out)
    assert b == pytest.approx(bottom, abs=MM_PER_PX)
    assert tp == pytest.approx(top, abs=MM_PER_PX)


def test_zero_pitch_is_identity_and_values_stay_in_range():
    x = torch.rand(3, 1, 64, 32)
    out = pitch_silhouette(x, torch.zeros(3), 1.25, 31.5)
    assert torch.allclose(out, x, atol=1e-5)  # float32 grid round-off
    out = pitch_silhouette(x, torch.tensor([0.0, 15.0, 30.0]), 1.25, 31.5)
    assert out.shape == x.shape and float(out.min()) >= 0 and float(out.max()) <= 1
    assert torch.allclose(out[0], x[0], atol=1e-5)


def test_pitch_fills_a_cavity():
    """A horizontal slot of 2 mm closes once the sweep (20 sin t mm) exceeds it."""
    x = box_image(80.0, 20.0)
    v = 100.0 - (np.arange(H) + 0.5) * MM_PER_PX
    x[0, 0, (v > 49.0) & (v < 51.0), :] = 0.0
    slot = (v > 49.5) & (v < 50.5)
    out1 = pitch_silhouette(x, torch.tensor([2.0]), MM_PER_PX, CENTRE_ROW)  # sweep 0.7 mm
    out2 = pitch_silhouette(x, torch.tensor([10.0]), MM_PER_PX, CENTRE_ROW)  # sweep 3.5 mm
    assert float(out1[0, 0, slot, 40].max()) < 0.5
    assert float(out2[0, 0, slot, 40].min()) >= 0.5
