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

from .networks import CorrectionGenerator, NetworkConfig, _conv, patch_discriminator
from .styles import STYLES


@dataclass(frozen=True)
class MultiStyleConfig(NetworkConfig):
    num_styles: int = len(STYLES)
    code_dim: int = 16  # a style code's length


class StyleCodes(nn.Module):
    """The code table (S, code_dim); a mix (B, S) of weights -> codes (B, code_dim)."""

    def __init__(self, num_styles: int, code_dim: int):
        super().__init__()
        self.table = nn.Parameter(torch.randn(num_styles, code_dim))

    def forward(self, weights: torch.Tensor) -> torch.Tensor:
        return weights.to(self.table.dtype) @ self.table


class AdaIN(nn.Module):
    """Instance-normalise each channel over time, then scale and shift it from the code.
    The affine map starts at (1, 0): before training the code changes nothing."""

    def __init__(self, ch: int, code_dim: int):
        super().__init__()
        self.norm = nn.InstanceNorm1d(ch, affine=False)
        self.affine = nn.Linear(code_dim, 2 * ch)
        nn.init.zeros_(self.affine.weight)
        nn.init.zeros_(self.affine.bias)

    def forward(self, x: torch.Tensor, code: torch.Tensor) -> torch.Tensor:
        gamma, beta = self.affine(code).unsqueeze(-1).chunk(2, dim=1)
        return (1 + gamma) * self.norm(x) + beta


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
        self.G = MultiStyleGenerator(cfg, combine)
        self.D = StyleDiscriminator(cfg)

    def generators(self):
        return list(self.G.parameters())

    def discriminators(self):
        return list(self.D.parameters())
