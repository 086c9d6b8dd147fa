"""The training augmentation (kornia + the dataset's disc occlusion), drawn from the
training generator. As in kornia and :mod:`finray.dataset.augment`, a batch's random
parameters are drawn first (:meth:`TrainAugment.draw`: an :class:`AugmentDraw`) and
applied apart (:meth:`TrainAugment.apply`), so that a batch replays exactly from its
draw (kept, or drawn again from the generator's state)."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from .config import AugmentConfig


@dataclass
class AugmentDraw:
    """Everything one batch's augmentation drew: kornia's parameters of each geometric
    jitter (image and stress map alike) and of the salt-and-pepper noise, which samples
    show the camera view (bool per sample), the occluding discs (``(sample, (H, W) bool
    mask)``) and each sample's camera pitch (deg; 0 where none). A part that is off is
    None (or empty)."""

    geometric: list[dict]
    camera: torch.Tensor | None
    occlusion: list[tuple[int, torch.Tensor]]
    pitch_deg: torch.Tensor | None
    noise: dict | None


class TrainAugment:
    """Random jitter (image and stress map alike), the camera view in place of the front
    view (``camera_p``; the stress map stays unjittered: it is the front view's),
    salt-and-pepper and occlusion (image only), drawn from the training generator, so
    training stays replayable; ``augment(x, s, gen[, x_camera])`` draws and applies."""

    def __init__(self, cfg: AugmentConfig, occlusion_levels: dict | None = None):
        import kornia.augmentation as K

        self.cfg = cfg
        self.geometric = []
        if cfg.affine_p > 0:
            self.geometric.append(
                K.RandomAffine(
                    cfg.degrees,
                    (cfg.translate, cfg.translate),
                    (1 - cfg.scale, 1 + cfg.scale),
                    p=cfg.affine_p,
                )
            )
        if cfg.perspective_p > 0:
            self.geometric.append(K.RandomPerspective(cfg.perspective, p=cfg.perspective_p))
        self.noise = (
            K.RandomSaltAndPepperNoise(
                amount=tuple(cfg.salt_pepper_amount), salt_vs_pepper=0.5, p=cfg.salt_pepper_p
            )
            if cfg.salt_pepper_p > 0
            else None
        )
        self.occlusion_levels = occlusion_levels

    def draw(
        self, x_shape: tuple[int, ...], s_channels: int, gen: torch.Generator, camera: bool = False
    ) -> AugmentDraw:
        """The parameters of one batch of inputs of ``x_shape`` (B, C, H, W) with stress
        maps of ``s_channels``, from ``gen`` (and kornia's, seeded from it); ``camera``:
        whether the batch comes with camera views to swap in."""
        from ..dataset.augment import sample_augment

        n, c, h, w = x_shape
        # kornia draws from torch's global generator: seeded from ours
        torch.manual_seed(int(torch.randint(0, 2**62, (1,), generator=gen)))
        geometric = [
            aug.forward_parameters(torch.Size((n, c + s_channels, h, w))) for aug in self.geometric
        ]
        swap = None
        if camera and self.cfg.camera_p > 0:
            swap = torch.rand(n, generator=gen) < self.cfg.camera_p
        occlusion = []
        if self.cfg.occlusion_p > 0:
            hit = torch.rand(n, generator=gen) < self.cfg.occlusion_p
            for i in torch.nonzero(hit).flatten().tolist():
                k = int(torch.randint(0, len(self.cfg.occlusion_levels), (1,), generator=gen))
                p = sample_augment(
                    int(torch.randint(0, 2**62, (1,), generator=gen)),
                    (h, w),
                    occlusion=self.cfg.occlusion_levels[k],
                    occlusion_levels=self.occlusion_levels,
                )
                occlusion.append((i, torch.from_numpy(p.disc_mask())))
        pitch = None
        if self.cfg.pitch_p > 0:
            tilt = torch.rand(n, generator=gen) < self.cfg.pitch_p
            pitch = torch.rand(n, generator=gen) * self.cfg.pitch_max_deg * tilt
        noise = (
            self.noise.forward_parameters(torch.Size(x_shape)) if self.noise is not None else None
        )
        return AugmentDraw(geometric, swap, occlusion, pitch, noise)

    def apply(
        self, x: torch.Tensor, s: torch.Tensor, d: AugmentDraw, x_camera: torch.Tensor | None = None
    ):
        """``(x, s)`` augmented by the draw ``d`` (no random draws: the same draw gives
        the same result)."""
        s_front = s
        if d.geometric:
            both = torch.cat([x, s], dim=1)
            for aug, params in zip(self.geometric, d.geometric):
                both = aug(both, params=params)
            x, s = both[:, : x.shape[1]], both[:, x.shape[1] :]
        if d.camera is not None and x_camera is not None:
            swap = d.camera.reshape(-1, 1, 1, 1)
            x = torch.where(swap, x_camera, x)
            s = torch.where(swap, s_front, s)
        if d.occlusion:
            x = x.clone()
            for i, mask in d.occlusion:
                x[i, :, mask] = 0.0
        if d.pitch_deg is not None:
            from ..dataset.pitch import pitch_silhouette

            x = pitch_silhouette(
                x, d.pitch_deg, self.cfg.mm_per_px, self.cfg.pitch_centre_row, self.cfg.extrusion_mm
            )
        if d.noise is not None:
            x = self.noise(x, params=d.noise)
        return x, s

    def __call__(
        self,
        x: torch.Tensor,
        s: torch.Tensor,
        gen: torch.Generator,
        x_camera: torch.Tensor | None = None,
    ):
        d = self.draw(tuple(x.shape), s.shape[1], gen, camera=x_camera is not None)
        return self.apply(x, s, d, x_camera)
