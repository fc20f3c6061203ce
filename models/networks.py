"""Generators and discriminators: temporal 1-D convolutions over motion words.

A word enters as (B, J*C, T): the J bones' C features are channels, the T = 60 frames
are the convolution's axis (features of a word (B, T, J, C) are reshaped by
``to_channels``/``from_channels``).

Generator (G_a2b, G_b2a): stem conv -> strided conv (T -> T/2) -> residual blocks at
half rate -> upsample -> conv -> zero-initialised head giving a correction ``delta``;
the output is ``representation.combine(x, delta)`` (residual formulation: input plus a
correction, in the representation's range). Starting from the identity map keeps the
content and the input's smoothness from the first step; the adversarial loss only has
to learn the style difference. The shortcut carries the input at full frame rate, so
the half-rate trunk cannot add quantisation jitter. Convolutions pad by replication,
so a word's edges behave like the motion simply continues (the edges are blended away
by the stream code anyway).

Discriminator (D_a, D_b): LSGAN patch discriminator (no sigmoid) over the word and its
frame-to-frame differences (scaled up so velocities are visible next to poses): style
such as exhaustion is as much in the dynamics as in the poses, and velocity inputs make
jitter easy to spot. Output (B, 1, T') of patch scores.

Sizes are chosen for the live budget: one word <= 2 ms, 64 words <= 40 ms on one core.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn


@dataclass(frozen=True)
class NetworkConfig:
    joints: int = 22
    channels: int = 3  # per joint, from the representation
    frames: int = 60
    g_hidden: int = 96
    g_blocks: int = 3
    g_kernel: int = 5
    d_hidden: int = 64
    d_velocity_scale: float = 60.0  # frame differences x fps: angular velocity per second

    @property
    def features(self) -> int:
        return self.joints * self.channels

    def to_dict(self) -> dict:
        return asdict(self)


def to_channels(words: torch.Tensor) -> torch.Tensor:
    """(B, T, J, C) -> (B, J*C, T)."""
    b, t, j, c = words.shape
    return words.reshape(b, t, j * c).transpose(1, 2)


def from_channels(x: torch.Tensor, joints: int) -> torch.Tensor:
    """(B, J*C, T) -> (B, T, J, C)."""
    b, f, t = x.shape
    return x.transpose(1, 2).reshape(b, t, joints, f // joints)


def _conv(cin: int, cout: int, k: int, stride: int = 1) -> nn.Conv1d:
    return nn.Conv1d(cin, cout, k, stride=stride, padding=k // 2, padding_mode="replicate")


class ResBlock(nn.Module):
    def __init__(self, ch: int, k: int):
        super().__init__()
        self.c1 = _conv(ch, ch, k)
        self.c2 = _conv(ch, ch, k)
        self.act = nn.LeakyReLU(0.2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.c2(self.act(self.c1(x)))


class Generator(nn.Module):
    def __init__(self, cfg: NetworkConfig, combine):
        super().__init__()
        f, h, k = cfg.features, cfg.g_hidden, cfg.g_kernel
        self.combine = combine  # representation.combine: (x, delta) -> output
        self.stem = _conv(f, h, k)
        self.down = nn.Conv1d(h, h, 4, stride=2, padding=1, padding_mode="replicate")
        self.blocks = nn.Sequential(*[ResBlock(h, 3) for _ in range(cfg.g_blocks)])
        self.up = nn.Upsample(scale_factor=2, mode="linear", align_corners=False)
        self.fuse = _conv(2 * h, h, 3)
        self.head = nn.Conv1d(h, f, 1)
        self.act = nn.LeakyReLU(0.2)
        nn.init.zeros_(self.head.weight)
        nn.init.zeros_(self.head.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        s = self.act(self.stem(x))
        y = self.blocks(self.act(self.down(s)))
        y = self.up(y)
        y = self.act(self.fuse(torch.cat([y, s], dim=1)))  # skip connection at full rate
        return self.combine(x, self.head(y))


class Discriminator(nn.Module):
    def __init__(self, cfg: NetworkConfig):
        super().__init__()
        f, h = cfg.features, cfg.d_hidden
        self.velocity_scale = cfg.d_velocity_scale
        self.net = nn.Sequential(
            nn.Conv1d(2 * f, h, 4, stride=2, padding=1), nn.LeakyReLU(0.2),
            nn.Conv1d(h, 2 * h, 4, stride=2, padding=1), nn.LeakyReLU(0.2),
            nn.Conv1d(2 * h, 2 * h, 3, padding=1), nn.LeakyReLU(0.2),
            nn.Conv1d(2 * h, 1, 3, padding=1),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        v = torch.diff(x, dim=2, prepend=x[:, :, :1]) * self.velocity_scale
        return self.net(torch.cat([x, v], dim=1))


class CycleGAN(nn.Module):
    """The four networks together, so one state dict holds a whole model."""

    def __init__(self, cfg: NetworkConfig, combine):
        super().__init__()
        self.cfg = cfg
        self.G_a2b = Generator(cfg, combine)
        self.G_b2a = Generator(cfg, combine)
        self.D_a = Discriminator(cfg)
        self.D_b = Discriminator(cfg)

    def generators(self):
        return list(self.G_a2b.parameters()) + list(self.G_b2a.parameters())

    def discriminators(self):
        return list(self.D_a.parameters()) + list(self.D_b.parameters())


def count_parameters(module: nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())
