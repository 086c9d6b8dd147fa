"""The paper's network: a convolutional encoder, a U-Net stress decoder and a force head.

Input: a deformation image ``(B, C, H, W)`` with ``H = 2 W`` (values in [0, 1]).
Outputs: the log-scale stress map ``(B, 1, H, W)`` and the force ``(B, n_forces)`` in N.

- Encoder: four stacks of two 3x3 convolutions (+ ReLU) and a 2x2 max-pool; the
  number of channels doubles at each stack (``base``, 2 ``base``, 4 ``base``, 8 ``base``).
  The latent ``h`` is the output of the last pool (``H/16 x W/16``).
- Stress decoder (U-Net expansion): per step an upsampling, a 2x2 convolution that
  halves the channels, concatenation with the encoder features of that resolution
  (skip connection) and two 3x3 convolutions (+ ReLU); a 1x1 convolution gives the map.
- Force head: ``h`` flattened through fully connected layers 128-64-32-8 and the
  output; sigmoid after the first, ReLU after the others, batch-norm after the
  first two. The force is predicted normalised; the mean and scale (N) are stored
  in the model's buffers, so ``forward`` returns newtons.
- Contact head (``NetConfig.contact``; ours, not the paper's): ``h`` flattened through
  fully connected layers 64-16 (ReLU) to one output, the height (mm, the finger's frame,
  the clamped base at 0) of the force-weighted centroid of the contact; normalised like
  the force (``contact_mean_mm``, ``contact_scale_mm``). A head of its own, not a third
  output of the force head, so that :mod:`finray.sim2real.adapt`, which re-fits the force head's
  last layers, sees the force head it knows. Read with :meth:`FinRayNet.contact`,
  :meth:`FinRayNet.force_contact` (no stress decoder) or :meth:`FinRayNet.forward_contact`.

Initial weights (``NetConfig.init``; the paper does not say): ``"he"`` draws each
convolution from N(0, gain^2 / fan_in) with zero bias (He et al. 2015; gain sqrt(2)
before a ReLU, 1 before none), so that the activations keep their scale through the
encoder's eight convolutions; ``"torch"`` keeps PyTorch's default (uniform, a third of
that variance), under which the latent came out ~1e-4 of the input's scale and the
force head's first batch-norm saw sigmoid outputs that differed by less than bfloat16
resolves (docs/studies/seeds.md, "Seeds, numeric types and what to expect").
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn

from .schema import schema_default


@dataclass
class NetConfig:
    in_channels: int = 3
    base_channels: int = schema_default("train.base_channels")
    height: int = schema_default("train.input_size", lambda hw: hw[0])
    width: int = schema_default("train.input_size", lambda hw: hw[1])
    n_forces: int = 1
    hidden: tuple[int, ...] = (128, 64, 32, 8)
    # initial weights: "he" or "torch" (PyTorch's default; module docstring)
    init: str = schema_default("train.init")
    contact: bool = False  # a contact-height head (module docstring); False: models before it

    def __post_init__(self):
        if self.init not in INITS:
            raise ValueError(f"init must be one of {INITS}, not {self.init!r}")
        if self.height % 16 or self.width % 16:
            raise ValueError(
                f"input size {self.height}x{self.width} must be divisible by 16 (four 2x2 poolings)"
            )
        if self.base_channels < 2 or self.base_channels % 2:
            raise ValueError("base_channels must be an even number >= 2")


INITS = ("he", "torch")
#: The contact head's hidden widths (module docstring).
CONTACT_HIDDEN = (64, 16)


def he_init(module: nn.Module) -> None:
    """He-normal convolutions (fan in, zero bias): gain sqrt(2) where a ReLU follows, 1
    elsewhere (the up-steps' 2x2 reductions, the stress output)."""
    mods = list(module.modules())
    for k, m in enumerate(mods):
        if isinstance(m, nn.Conv2d):
            relu = k + 1 < len(mods) and isinstance(mods[k + 1], nn.ReLU)
            nn.init.kaiming_normal_(
                m.weight, mode="fan_in", nonlinearity="relu" if relu else "linear"
            )
            nn.init.zeros_(m.bias)


def _double_conv(c_in: int, c_out: int) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, 3, padding=1),
        nn.ReLU(inplace=True),
        nn.Conv2d(c_out, c_out, 3, padding=1),
        nn.ReLU(inplace=True),
    )


class UpStep(nn.Module):
    """Upsample, 2x2 convolution halving the channels, skip concat, two 3x3 convs."""

    def __init__(self, c_in: int, c_skip: int, c_out: int):
        super().__init__()
        self.up = nn.Upsample(scale_factor=2, mode="nearest")
        # 2x2 "up-convolution"; pad right/bottom by one so the size is kept
        self.reduce = nn.Sequential(nn.ZeroPad2d((0, 1, 0, 1)), nn.Conv2d(c_in, c_in // 2, 2))
        self.conv = _double_conv(c_in // 2 + c_skip, c_out)

    def forward(self, x: torch.Tensor, skip: torch.Tensor) -> torch.Tensor:
        x = self.reduce(self.up(x))
        return self.conv(torch.cat([x, skip], dim=1))


class FinRayNet(nn.Module):
    """Encoder, U-Net stress decoder and force head (see module docstring)."""

    def __init__(self, cfg: NetConfig | None = None):
        super().__init__()
        self.cfg = cfg = cfg or NetConfig()
        b = cfg.base_channels
        chans = [b, 2 * b, 4 * b, 8 * b]
        self.down = nn.ModuleList()
        c_prev = cfg.in_channels
        for c in chans:
            self.down.append(_double_conv(c_prev, c))
            c_prev = c
        self.pool = nn.MaxPool2d(2)
        # decoder: latent (8b) -> 4b -> 2b -> b -> b/2
        outs = [4 * b, 2 * b, b, b // 2]
        self.up = nn.ModuleList()
        c_prev = chans[-1]
        for c_skip, c_out in zip(reversed(chans), outs):
            self.up.append(UpStep(c_prev, c_skip, c_out))
            c_prev = c_out
        self.stress_out = nn.Conv2d(c_prev, 1, 1)
        n_latent = chans[-1] * (cfg.height // 16) * (cfg.width // 16)
        h = cfg.hidden
        layers: list[nn.Module] = [
            nn.Flatten(),
            nn.Linear(n_latent, h[0]),
            nn.Sigmoid(),
            nn.BatchNorm1d(h[0]),
        ]
        layers += [nn.Linear(h[0], h[1]), nn.ReLU(inplace=True), nn.BatchNorm1d(h[1])]
        for a, c in zip(h[1:-1], h[2:]):
            layers += [nn.Linear(a, c), nn.ReLU(inplace=True)]
        layers.append(nn.Linear(h[-1], cfg.n_forces))
        self.force_head = nn.Sequential(*layers)
        self.register_buffer("force_mean_N", torch.zeros(cfg.n_forces))
        self.register_buffer("force_scale_N", torch.ones(cfg.n_forces))
        if cfg.init == "he":
            he_init(self)
        if cfg.contact:  # drawn last: the other layers' initial weights are a model's without it
            self.contact_head = nn.Sequential(
                nn.Flatten(),
                nn.Linear(n_latent, CONTACT_HIDDEN[0]),
                nn.ReLU(inplace=True),
                nn.Linear(CONTACT_HIDDEN[0], CONTACT_HIDDEN[1]),
                nn.ReLU(inplace=True),
                nn.Linear(CONTACT_HIDDEN[1], 1),
            )
            self.register_buffer("contact_mean_mm", torch.zeros(1))
            self.register_buffer("contact_scale_mm", torch.ones(1))

    def encode(self, x: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor]]:
        skips = []
        for block in self.down:
            x = block(x)
            skips.append(x)
            x = self.pool(x)
        return x, skips

    def forward_normalised(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Stress map and force in normalised units (what the loss sees)."""
        h, skips = self.encode(x)
        return self.decode(h, skips), self.force_head(h)

    def decode(self, h: torch.Tensor, skips: list[torch.Tensor]) -> torch.Tensor:
        """The log-stress map from the encoder's latent and skip features."""
        y = h
        for step, skip in zip(self.up, reversed(skips)):
            y = step(y, skip)
        return self.stress_out(y)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Stress map (log scale) and force in N."""
        stress, f = self.forward_normalised(x)
        return stress, f * self.force_scale_N + self.force_mean_N

    def force(self, x: torch.Tensor) -> torch.Tensor:
        """Force in N only: the encoder and the force head, without the stress decoder
        (about 40 % of the full network's cost; for control loops)."""
        h, _ = self.encode(x)
        return self.force_head(h) * self.force_scale_N + self.force_mean_N

    def contact(self, x: torch.Tensor) -> torch.Tensor:
        """Contact height (B,) in mm (the finger's frame, the clamped base at 0): the
        encoder and the contact head only. Meaningful where the finger is pushed
        (training's frames above ``train.contact_min_force_N``)."""
        h, _ = self.encode(x)
        return self.contact_of_latent(h)

    def force_contact(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Force (B, n_forces) in N and contact height (B,) in mm, without the stress
        decoder (one encoder pass)."""
        h, _ = self.encode(x)
        return self.force_head(h) * self.force_scale_N + self.force_mean_N, self.contact_of_latent(
            h
        )

    def forward_contact(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Stress map (log scale), force (B, n_forces) in N and contact height (B,) in mm."""
        stress, f, c = self.forward_normalised_all(x)
        return (
            stress,
            f * self.force_scale_N + self.force_mean_N,
            c * self.contact_scale_mm + self.contact_mean_mm,
        )

    def forward_normalised_all(self, x: torch.Tensor):
        """Stress map, force and contact height (B,) in normalised units (what the loss
        sees); the contact is None for a model without the contact head."""
        h, skips = self.encode(x)
        c = self.contact_head(h)[:, 0] if self.cfg.contact else None
        return self.decode(h, skips), self.force_head(h), c

    def contact_of_latent(self, h: torch.Tensor) -> torch.Tensor:
        """Contact height (B,) in mm of encoder latents ``h`` (B, C, h, w), or flattened
        (B, F) as sim-to-real keeps them."""
        if not self.cfg.contact:
            raise RuntimeError("this model has no contact head (NetConfig.contact is False)")
        return self.contact_head(h)[:, 0] * self.contact_scale_mm + self.contact_mean_mm

    def set_contact_normalisation(self, mean_mm: float, scale_mm: float) -> None:
        self.contact_mean_mm.fill_(float(mean_mm))
        self.contact_scale_mm.fill_(float(scale_mm))

    def normalise_contact(self, c_mm: torch.Tensor) -> torch.Tensor:
        return (c_mm - self.contact_mean_mm) / self.contact_scale_mm

    def set_force_normalisation(self, mean_N, scale_N) -> None:
        self.force_mean_N.copy_(torch.as_tensor(mean_N, dtype=torch.float32).reshape(-1))
        self.force_scale_N.copy_(torch.as_tensor(scale_N, dtype=torch.float32).reshape(-1))

    def normalise_force(self, f_N: torch.Tensor) -> torch.Tensor:
        return (f_N - self.force_mean_N) / self.force_scale_N

    def config_dict(self) -> dict:
        d = asdict(self.cfg)
        d["hidden"] = list(d["hidden"])
        return d


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters() if p.requires_grad)
