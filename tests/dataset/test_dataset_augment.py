"""Dataset corruptions: occlusion disc sizes, salt-and-pepper density, exact replay."""

from __future__ import annotations

import numpy as np
import pytest

from finray.dataset import (
    OCCLUSION_LEVELS,
    AugmentParams,
    apply_augment,
    augment_seed,
    sample_augment,
)


def measured_disc_fraction(params: AugmentParams) -> float:
    """Occlude an all-white image and measure the widest occluded run / image width."""
    img = apply_augment(np.ones(params.shape, np.float32), params, occluder_value=0.0)
    occ = img == 0
    if not occ.any():
        return 0.0
    cols = np.nonzero(occ.any(axis=0))[0]
    rows = np.nonzero(occ.any(axis=1))[0]
    # a disc: as wide as tall, and fully inside the image
    assert cols.max() - cols.min() == rows.max() - rows.min()
    return (cols.max() - cols.min() + 1) / params.shape[1]


@pytest.mark.parametrize("shape", [(128, 64), (64, 32)])
@pytest.mark.parametrize("level", ["none", "low", "medium", "high"])
def test_occlusion_diameter_is_in_the_level_range(shape, level):
    lo, hi = OCCLUSION_LEVELS[level]
    fracs = []
    for seed in range(300):
        p = sample_augment(augment_seed(7, "scene", seed, level), shape, occlusion=level)
        f = measured_disc_fraction(p)
        assert lo - 1e-9 <= f <= hi + 1e-9, (level, seed, f)
        fracs.append(f)
    if level != "none":
        # the whole range is used, not one size
        assert len(set(fracs)) >= 3
        # the disc lies inside the image and is round: area close to pi d^2 / 4
        p = sample_augment(3, shape, occlusion=level)
        d = p.disc_diameter_px
        assert p.disc_mask().sum() == pytest.approx(np.pi * d * d / 4, rel=0.25 if d < 5 else 0.1)


def test_occlusion_levels_match_the_issue():
    assert OCCLUSION_LEVELS["low"] == (0.10, 0.30)
    assert OCCLUSION_LEVELS["medium"] == (0.40, 0.80)
    assert OCCLUSION_LEVELS["high"][0] >= 0.80 and OCCLUSION_LEVELS["high"][1] <= 1.0


@pytest.mark.parametrize("density", [0.01, 0.05, 0.1, 0.3])
def test_salt_and_pepper_density_matches_its_setting(density):
    shape = (1000, 1000)
    p = sample_augment(11, shape, noise="custom", noise_levels={"custom": density})
    img = apply_augment(np.full(shape, 0.5, np.float32), p)
    changed = (img != 0.5).mean()
    assert changed == pytest.approx(density, rel=0.01)
    salt, pepper = (img == 1.0).mean(), (img == 0.0).mean()
    assert salt / changed == pytest.approx(0.5, abs=0.01)
    assert pepper / changed == pytest.approx(0.5, abs=0.01)
    # and on every network-sized image, to the pixel
    for seed in range(20):
        q = sample_augment(seed, (128, 64), noise="custom", noise_levels={"custom": density})
        n = (apply_augment(np.full((128, 64), 0.5), q) != 0.5).sum()
        assert abs(n - density * 128 * 64) <= 0.5


def test_same_seed_replays_the_same_augmentation():
    img = np.random.default_rng(0).integers(0, 256, (128, 64), dtype=np.uint8)
    seed = augment_seed(0, "circle_d10_steel_h30_p0", 17, "high", "medium")
    a = sample_augment(seed, img.shape, noise="high", occlusion="medium")
    b = sample_augment(seed, img.shape, noise="high", occlusion="medium")
    np.testing.assert_array_equal(apply_augment(img, a), apply_augment(img, b))
    # another seed gives another corruption; applying never changes the input
    c = sample_augment(seed + 1, img.shape, noise="high", occlusion="medium")
    assert not np.array_equal(apply_augment(img, a), apply_augment(img, c))
    img0 = img.copy()
    apply_augment(img, a)
    np.testing.assert_array_equal(img, img0)


def test_seeds_are_stable_and_distinct():
    assert augment_seed(0, "a", 1) == augment_seed(0, "a", 1)
    assert len({augment_seed(0, "a", k) for k in range(1000)}) == 1000
    assert augment_seed(0, "a", 1) != augment_seed(1, "a", 1)
    # a fixed value: the seed must not change between runs or machines
    assert augment_seed(0, "scene", 3, "low") == augment_seed(0, "scene", 3, "low")


def test_uint8_and_colour_images():
    rgb = np.full((64, 32, 3), 128, np.uint8)
    p = sample_augment(5, (64, 32), noise="high", occlusion="high")
    out = apply_augment(rgb, p, occluder_value=0.0)
    assert out.dtype == np.uint8
    assert set(np.unique(out)) <= {0, 128, 255}
    assert (out[p.disc_mask()] != 128).all()


def test_unknown_level_is_rejected():
    with pytest.raises(ValueError, match="occlusion level"):
        sample_augment(0, (64, 32), occlusion="extreme")


def test_training_augmentation_replays_from_its_draw():
    """The training augmentation draws a batch's parameters apart from applying them:
    the same draw applied twice gives the same batch, the same generator state the same
    draw, and a call is its draw applied; every part does something (jitter, camera
    swap, occlusion discs, pitch, noise)."""
    import torch

    from finray.train.augment import TrainAugment
    from finray.train.config import AugmentConfig

    aug = TrainAugment(
        AugmentConfig(
            affine_p=0.5,
            perspective_p=0.5,
            salt_pepper_p=0.5,
            occlusion_p=0.5,
            pitch_p=0.5,
            camera_p=0.5,
        )
    )
    g = torch.Generator().manual_seed(0)
    x, s, xc = (
        torch.rand(12, 1, 64, 32, generator=g),
        torch.rand(12, 1, 64, 32, generator=g),
        torch.rand(12, 1, 64, 32, generator=g),
    )
    d = aug.draw(tuple(x.shape), 1, torch.Generator().manual_seed(3), camera=True)
    assert d.camera.any() and d.occlusion and (d.pitch_deg > 0).any() and len(d.geometric) == 2
    a, b = aug.apply(x, s, d, xc), aug.apply(x, s, d, xc)
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    again = aug.draw(tuple(x.shape), 1, torch.Generator().manual_seed(3), camera=True)
    c = aug.apply(x, s, again, xc)
    assert torch.equal(a[0], c[0]) and torch.equal(a[1], c[1])
    called = aug(x, s, torch.Generator().manual_seed(3), xc)
    assert torch.equal(a[0], called[0]) and torch.equal(a[1], called[1])
    assert not torch.equal(a[0], x)
