"""How a style code conditions a generator (seed 001, MotionGAN): the learned code table
and adaptive instance normalisation (AdaIN). Shared by the temporal generator
(``multistyle``) and the skeleton-graph one (``graph``)."""

from __future__ import annotations

import torch
from torch import nn

from .networks import INFERENCE_FORMS


class StyleCodes(nn.Module):
    """The code table (S, code_dim); a mix (B, S) of weights -> codes (B, code_dim)."""

    def __init__(self, num_styles: int, code_dim: int):
        super().__init__()
        self.table = nn.Parameter(torch.randn(num_styles, code_dim))

    def forward(self, weights: torch.Tensor) -> torch.Tensor:
        return weights.to(self.table.dtype) @ self.table


class RowStyleCodes(StyleCodes):
    """``StyleCodes`` for inference: a mix's codes as a product and a sum, so one word's
    code has the same bits alone as in a batch (``networks.INFERENCE_FORMS``)."""

    def forward(self, weights: torch.Tensor) -> torch.Tensor:
        return (weights.to(self.table.dtype).unsqueeze(-1) * self.table).sum(-2)


INFERENCE_FORMS[StyleCodes] = RowStyleCodes


class RowInstanceNorm1d(nn.InstanceNorm1d):
    """``InstanceNorm1d`` for inference, as reductions over time and elementwise steps,
    which keep the frames-as-rows layout ``networks.RowConv1d`` hands on (the native
    kernel returned (B, C, T) rows, which the next convolution copied back: 1.3x the
    multi-style generator's time for 64 words, ``bench/bench_models.py``). Each word's
    statistics are its own, so its bits do not depend on the batch."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.affine or self.track_running_stats:
            raise ValueError("RowInstanceNorm1d normalises without affine weights or running statistics")
        centred = x - x.mean(2, keepdim=True)
        return centred * torch.rsqrt((centred * centred).mean(2, keepdim=True) + self.eps)


INFERENCE_FORMS[nn.InstanceNorm1d] = RowInstanceNorm1d


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
