"""The training augmentation (kornia + the dataset's disc occlusion), drawn from the
training generator."""
from __future__ import annotations

import torch

from .config import AugmentConfig


class TrainAugment:
    """Random jitter (image and stress map alike), the camera view in place of the front
    view (``camera_p``; the stress map stays unjittered: it is the front view's),
    salt-and-pepper and occlusion (image only), drawn from the training generator, so
    training stays replayable."""

    def __init__(self, cfg: AugmentConfig, occlusion_levels: dict | None = None):
        import kornia.augmentation as K

        self.cfg = cfg
        self.geometric = []
        if cfg.affine_p > 0:
            self.geometric.append(K.RandomAffine(cfg.degrees, (cfg.translate, cfg.translate),
                                                 (1 - cfg.scale, 1 + cfg.scale), p=cfg.affine_p))
        if cfg.perspective_p > 0:
            self.geometric.append(K.RandomPerspective(cfg.perspective, p=cfg.perspective_p))
        self.noise = (K.RandomSaltAndPepperNoise(amount=tuple(cfg.salt_pepper_amount),
                                                 salt_vs_pepper=0.5, p=cfg.salt_pepper_p)
                      if cfg.salt_pepper_p > 0 else None)
        self.occlusion_levels = occlusion_levels

    def __call__(self, x: torch.Tensor, s: torch.Tensor, gen: torch.Generator,
                 x_camera: torch.Tensor | None = None):
        from ..dataset.augment import sample_augment

        # kornia draws from torch's global generator: seed it from ours (replayable)
        torch.manual_seed(int(torch.randint(0, 2**62, (1,), generator=gen)))
        s_front = s
        if self.geometric:
            both = torch.cat([x, s], dim=1)
            for aug in self.geometric:
                both = aug(both)
            x, s = both[:, :x.shape[1]], both[:, x.shape[1]:]
        if x_camera is not None and self.cfg.camera_p > 0:
            draw = (torch.rand(len(x), generator=gen) < self.cfg.camera_p).reshape(-1, 1, 1, 1)
            x = torch.where(draw, x_camera, x)
            s = torch.where(draw, s_front, s)
        if self.cfg.occlusion_p > 0:
            x = x.clone()
            draw = torch.rand(len(x), generator=gen) < self.cfg.occlusion_p
            for i in torch.nonzero(draw).flatten().tolist():
                k = int(torch.randint(0, len(self.cfg.occlusion_levels), (1,), generator=gen))
                p = sample_augment(int(torch.randint(0, 2**62, (1,), generator=gen)),
                                   tuple(x.shape[2:]), occlusion=self.cfg.occlusion_levels[k],
                                   occlusion_levels=self.occlusion_levels)
                x[i, :, torch.from_numpy(p.disc_mask())] = 0.0
        if self.cfg.pitch_p > 0:
            from ..dataset.pitch import pitch_silhouette

            draw = torch.rand(len(x), generator=gen) < self.cfg.pitch_p
            pitch = torch.rand(len(x), generator=gen) * self.cfg.pitch_max_deg * draw
            x = pitch_silhouette(x, pitch, self.cfg.mm_per_px, self.cfg.pitch_centre_row,
                                 self.cfg.extrusion_mm)
        if self.noise is not None:
            x = self.noise(x)
        return x, s
