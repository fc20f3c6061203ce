"""The multi-style generator G(x, s) and its style-aware discriminator (seed 001, MotionGAN).

One generator restyles a word towards any style of ``styles.STYLES``: the style enters
as a learned code (one row of ``StyleCodes`` per style) through adaptive instance
normalisation (AdaIN) in the residual blocks, the paper's way of conditioning one network
on a continuous style space. Because a code is a vector, a *mix* of styles is simply the
weighted sum of their codes: G takes a (B, S) weight vector per word, so two styles can
be interpolated and every word of a batch can have its own mix (one batched call for
performers in different styles).

Everything else is the pair generator's (``networks.Generator``), for the same reasons:
stem conv -> strided conv -> residual blocks at half rate -> fixed upsampling -> fuse with
the full-rate skip -> zero-initialised head giving a correction, projected on the cubic
B-spline (``correction_knots``) so it cannot jitter, added to the input
(``representation.combine``). Zero head = the identity map at the start, whatever the
code. ``intensity`` scales the correction (0 = the input, 1 = the style).

Only the target style is given: the source style is not an input (StarGAN), so any
performance can be restyled into any style; training knows each word's own style from
the labels and uses it for the cycle back (``train_multistyle``).

Discriminator: the pair model's LSGAN patch discriminator over poses and velocities as a
shared trunk, with one output channel (head) per style; a word is scored by the head of
the style it is real in or was made to be.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from .conditioning import AdaIN, StyleCodes
from .graph import GraphStyleGenerator
from .networks import CorrectionGenerator, NetworkConfig, _conv, patch_discriminator
from .styles import STYLES


@dataclass(frozen=True)
class MultiStyleConfig(NetworkConfig):
    num_styles: int = len(STYLES)
    code_dim: int = 16  # a style code's length
    # Channels per bone of the skeleton-graph generator (``graph.py``, seed 003); 0: the
    # temporal-conv generator (all bones' features as channels of one 1-D conv).
    graph_channels: int = 0

    MAY_BE_ZERO = ("correction_knots", "graph_channels")


class AdaINResBlock(nn.Module):
    def __init__(self, ch: int, k: int, code_dim: int):
        super().__init__()
        self.c1 = _conv(ch, ch, k)
        self.n1 = AdaIN(ch, code_dim)
        self.c2 = _conv(ch, ch, k)
        self.n2 = AdaIN(ch, code_dim)
        self.act = nn.LeakyReLU(0.2)

    def forward(self, x: torch.Tensor, code: torch.Tensor) -> torch.Tensor:
        y = self.act(self.n1(self.c1(x), code))
        return x + self.n2(self.c2(y), code)


class MultiStyleGenerator(CorrectionGenerator):
    def build_conditioning(self, cfg: MultiStyleConfig) -> None:
        self.codes = StyleCodes(cfg.num_styles, cfg.code_dim)

    def build_blocks(self, cfg: MultiStyleConfig) -> nn.Module:
        return nn.ModuleList([AdaINResBlock(cfg.g_hidden, 3, cfg.code_dim) for _ in range(cfg.g_blocks)])

    def forward(self, x: torch.Tensor, weights: torch.Tensor, intensity: torch.Tensor | None = None) -> torch.Tensor:
        """x (B, F, T); weights (B, S) style mix per word; intensity (B,) or None (= 1)."""
        code = self.codes(weights)
        skip, y = self.encode(x)
        for block in self.blocks:
            y = block(y, code)
        scale = None if intensity is None else intensity.to(x.dtype).reshape(-1, 1, 1)  # x's dtype is delta's
        return self.correct(x, skip, y, scale)


# ``stylecast train --styles all --generator NAME``: the network settings each name stands
# for. 24 channels per bone (134k parameters against the temporal generator's 317k) made a
# training step 2.9x the temporal one's on this machine (16: 1.8x, 87k).
GENERATORS = {"temporal": {}, "graph": {"graph_channels": 24}}


def make_generator(cfg: MultiStyleConfig, combine) -> nn.Module:
    """The generator ``cfg`` describes: over the bone graph or over time only."""
    return (GraphStyleGenerator if cfg.graph_channels else MultiStyleGenerator)(cfg, combine)


class StyleDiscriminator(nn.Module):
    """Shared trunk, one LSGAN patch head per style: (x, style index (B,)) -> (B, 1, T')."""

    def __init__(self, cfg: MultiStyleConfig):
        super().__init__()
        self.velocity_scale = cfg.d_velocity_scale
        self.net = patch_discriminator(cfg, heads=cfg.num_styles)

    def forward(self, x: torch.Tensor, style: torch.Tensor) -> torch.Tensor:
        v = torch.diff(x, dim=2, prepend=x[:, :, :1]) * self.velocity_scale
        heads = self.net(torch.cat([x, v], dim=1))  # (B, S, T')
        index = style.reshape(-1, 1, 1).expand(-1, 1, heads.shape[-1])
        return heads.gather(1, index)


class MultiStyleGAN(nn.Module):
    """Generator and discriminator together, so one state dict holds a whole model."""

    def __init__(self, cfg: MultiStyleConfig, combine):
        super().__init__()
        self.cfg = cfg
        self.G = make_generator(cfg, combine)
        self.D = StyleDiscriminator(cfg)

    def generators(self):
        return list(self.G.parameters())

    def discriminators(self):
        return list(self.D.parameters())
