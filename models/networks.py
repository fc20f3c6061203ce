"""Generators and discriminators: temporal 1-D convolutions over motion words.

A word enters as (B, J*C, T): the J bones' C features are channels, the T = 60 frames
are the convolution's axis (features of a word (B, T, J, C) are reshaped by
``to_channels``/``from_channels``).

Generator (G_a2b, G_b2a): stem conv -> strided conv (T -> T/2) -> residual blocks at
half rate -> upsample -> conv -> zero-initialised head giving a correction ``delta``;
the output is ``representation.combine(x, delta)`` (residual formulation: input plus a
correction, in the representation's range). Starting from the identity map keeps the
content and the input's smoothness from the first step; the adversarial loss only has
to learn the style difference. Convolutions pad by replication, so a word's edges
behave like the motion simply continues (the edges are blended away by the stream
code anyway).

Smooth by construction (``correction_knots`` > 0): the correction is projected onto a
cubic B-spline basis of that many control points spread over the word (a fixed
least-squares projection, ``smooth_projection``), so it cannot carry content faster
than the knot spacing: the generator can bend the posture and reshape the slow
dynamics, but it cannot add jitter, whatever it learns. Measured in ``stylecast eval``
(jerk ratio); without it (0, the first shipped model) the free full-rate correction
learnt to shake hands and feet (jerk x2.3 the input's). Upsampling is a fixed matrix
product too (``linear_upsample_matrix``: exactly ``nn.Upsample(mode="linear")``), whose
backward pass, unlike that module's on CUDA, is deterministic.

Discriminator (D_a, D_b): LSGAN patch discriminator (no sigmoid) over the word and its
frame-to-frame differences (scaled up so velocities are visible next to poses): style
such as exhaustion is as much in the dynamics as in the poses, and velocity inputs make
jitter easy to spot. Output (B, 1, T') of patch scores.

Sizes are chosen for the live budget: one word <= 2 ms, 64 words <= 40 ms on one core.
"""

from __future__ import annotations

import copy
import functools
from dataclasses import asdict, dataclass

import numpy as np
import torch
import torch.nn.functional as F
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
    # Control points of the cubic B-spline the correction is projected on (0 = none, the
    # unconstrained full-rate correction of the first shipped model). 8 over a 60-frame
    # word: ~7.5 frames between knots, nothing faster than ~4 Hz survives.
    correction_knots: int = 8

    MAY_BE_ZERO = ("correction_knots",)  # settings where 0 means "off" (a ClassVar: no field)

    def __post_init__(self) -> None:
        if self.correction_knots and not 4 <= self.correction_knots <= self.frames:
            raise ValueError(f"correction_knots must be 0 (off) or between 4 (a cubic) and {self.frames}, "
                             f"got {self.correction_knots}")

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


# The fixed matrices below are built in numpy (construction time only, never on the hot
# path) so that a network outlined on torch's "meta" device still gets real values.

def linear_upsample_matrix(n: int) -> torch.Tensor:
    """(n, 2n) matrix M with x @ M == nn.Upsample(scale_factor=2, mode="linear",
    align_corners=False)(x) for x (..., n): half-pixel centres, edges clamped."""
    pos = np.clip((np.arange(2 * n) + 0.5) / 2 - 0.5, 0, n - 1)
    lo = np.floor(pos).astype(int)
    hi = np.minimum(lo + 1, n - 1)
    m = np.zeros((n, 2 * n))
    cols = np.arange(2 * n)
    np.add.at(m, (lo, cols), 1 - (pos - lo))
    np.add.at(m, (hi, cols), pos - lo)
    return torch.from_numpy(m.astype(np.float32))


def bspline_basis(frames: int, knots: int, degree: int = 3) -> np.ndarray:
    """(frames, knots) clamped uniform B-spline basis sampled at each frame (rows sum to 1;
    the first and last frames sit exactly on the first and last control points)."""
    t = np.concatenate([np.zeros(degree), np.linspace(0, 1, knots - degree + 1), np.ones(degree)])
    x = np.linspace(0, 1, frames)
    b = np.stack([(t[i] <= x) & (x < t[i + 1]) for i in range(len(t) - 1)], axis=1).astype(np.float64)
    b[-1, knots - 1] = 1.0  # x = 1 closes the last non-empty knot interval
    for d in range(1, degree + 1):  # Cox-de Boor recursion, vectorised over frames
        cols = []
        for i in range(len(t) - 1 - d):
            left = (x - t[i]) / (t[i + d] - t[i]) if t[i + d] > t[i] else 0.0
            right = (t[i + d + 1] - x) / (t[i + d + 1] - t[i + 1]) if t[i + d + 1] > t[i + 1] else 0.0
            cols.append(left * b[:, i] + right * b[:, i + 1])
        b = np.stack(cols, axis=1)
    return b


def smooth_projection(frames: int, knots: int) -> torch.Tensor:
    """(frames, frames) least-squares projection onto the B-spline basis: x @ P is the
    smooth curve closest to x (P = B (B^T B)^-1 B^T, symmetric)."""
    b = bspline_basis(frames, knots)
    return torch.from_numpy((b @ np.linalg.solve(b.T @ b, b.T)).astype(np.float32))


def register_fixed_matrices(module: nn.Module, cfg: NetworkConfig) -> None:
    """The fixed matrices of every generator, buffers rebuilt from ``cfg`` (never saved):
    ``upsample`` from the strided conv's half rate back to the word's frames, and
    ``smooth``, the B-spline projection of the correction (None when off)."""
    half = (cfg.frames + 2 - 4) // 2 + 1  # length after the strided conv (kernel 4, stride 2, padding 1)
    module.register_buffer("upsample", linear_upsample_matrix(half), persistent=False)
    module.register_buffer("smooth", smooth_projection(cfg.frames, cfg.correction_knots)
                           if cfg.correction_knots else None, persistent=False)


def zero_head(cin: int, cout: int) -> nn.Conv1d:
    """A generator's last layer (1x1), its weights zero: the correction starts at nothing,
    so a new generator is the identity map. (Made as a plain conv first, so it draws from
    torch's generator as before: a seed gives the shipped models again.)"""
    head = nn.Conv1d(cin, cout, 1)
    nn.init.zeros_(head.weight)
    nn.init.zeros_(head.bias)
    return head


def apply_correction(x: torch.Tensor, delta: torch.Tensor, smooth: torch.Tensor | None, scale, combine) -> torch.Tensor:
    """Every generator's last step: the raw correction (B, F, T) projected on the B-spline
    (``smooth``, None = free), scaled by the intensity (``scale`` (B, 1, 1) or None) and put
    on the input by the representation's ``combine``."""
    if smooth is not None:
        delta = delta @ smooth
    if scale is not None:
        delta = delta * scale
    return combine(x, delta)


class ResBlock(nn.Module):
    def __init__(self, ch: int, k: int):
        super().__init__()
        self.c1 = _conv(ch, ch, k)
        self.c2 = _conv(ch, ch, k)
        self.act = nn.LeakyReLU(0.2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.c2(self.act(self.c1(x)))


class CorrectionGenerator(nn.Module):
    """What every stylecast generator shares around its residual blocks: stem, strided
    conv, fixed upsampling, the full-rate skip, the zero-initialised head and the B-spline
    projection of the correction (the pair ``Generator`` and ``multistyle``'s generator
    differ only in their blocks and what conditions them). The layers are built in one
    fixed order (conditioning, stem, down, blocks, fuse, head), the order their weights
    draw from torch's generator: a seed gives the shipped models again."""

    def __init__(self, cfg: NetworkConfig, combine):
        super().__init__()
        f, h, k = cfg.features, cfg.g_hidden, cfg.g_kernel
        self.combine = combine  # representation.combine: (x, delta) -> output
        self.build_conditioning(cfg)
        self.stem = _conv(f, h, k)
        self.down = nn.Conv1d(h, h, 4, stride=2, padding=1, padding_mode="replicate")
        self.blocks = self.build_blocks(cfg)
        register_fixed_matrices(self, cfg)
        self.fuse = _conv(2 * h, h, 3)
        self.head = zero_head(h, f)
        self.act = nn.LeakyReLU(0.2)

    def build_conditioning(self, cfg) -> None:
        """Modules that condition the blocks (none for the pair generator)."""

    def build_blocks(self, cfg) -> nn.Module:
        raise NotImplementedError

    def encode(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, F, T) -> the full-rate features (skip) and the half-rate ones for the blocks."""
        s = self.act(self.stem(x))
        return s, self.act(self.down(s))

    def correct(self, x: torch.Tensor, skip: torch.Tensor, y: torch.Tensor, scale=None) -> torch.Tensor:
        """The blocks' output -> the smooth correction, (optionally scaled) put on x."""
        y = y @ self.upsample
        y = self.act(self.fuse(torch.cat([y, skip], dim=1)))  # skip connection at full rate
        return apply_correction(x, self.head(y), self.smooth, scale, self.combine)


class Generator(CorrectionGenerator):
    def build_blocks(self, cfg: NetworkConfig) -> nn.Module:
        return nn.Sequential(*[ResBlock(cfg.g_hidden, 3) for _ in range(cfg.g_blocks)])

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        skip, y = self.encode(x)
        return self.correct(x, skip, self.blocks(y))


# Inference forms of layers whose CPU kernels round a word's result differently with what
# else shares its batch and with the thread count: oneDNN's convolution picks its kernel
# by both, and a product of one row (one word's style code) goes to a matrix-vector kernel
# that rounds unlike the matrix-matrix one. That rounding (1e-7) differed between the
# daemon's per-tick batches and ``restyle``'s whole clip, and the foot lock amplifies it
# at nearly straight knees: ``serve`` and ``restyle --live`` parted by up to 3.4e-4 degrees
# on held-out clips with ``--feet stance``, where the issue allows 1e-4. The forms below
# give every word the same bits in any batch on any thread count
# (tests/test_batch_invariance.py checks the shipped models); training keeps the fast
# kernels. ``batch_invariant`` swaps them in (``INFERENCE_FORMS``, below the two forms);
# other modules register theirs (``conditioning.RowStyleCodes``).


@functools.lru_cache(maxsize=64)
def _padded_frame_index(length: int, pad: int, count: int, mode: str, device: torch.device) -> torch.Tensor:
    """Which input frame each of ``count`` padded frames reads: the edge frames around the
    word for replication (and past it, where whole stride groups overrun; only zero taps
    read those), else frame ``length``, a zero frame the caller appends."""
    index = torch.arange(count) - pad
    if mode == "replicate":
        index = index.clamp(0, length - 1)
    else:
        index[(index < 0) | (index >= length)] = length
    return index.to(device)


class RowConv1d(nn.Conv1d):
    """A ``Conv1d`` as matrix products over rows of frames: MKL's matrix product rounds
    each row alike for any row count and thread count, at the generators' widths (66 to
    192 columns; with as few as 7 output columns, MKL's AVX2 kernels on an AMD EPYC
    rounded a row differently with where the rows start in memory, which shifted taps
    change: ``tests/test_batch_invariance.py`` checks the shipped models themselves).

    How, and why this way: the words' frames become rows ((B, T, C), padded), and each
    kernel tap is one product of the frame rows shifted by that tap, accumulated in place
    (``addmm_``) over all words at once; the rows that straddle two words are computed
    and dropped. A stride ``s`` groups ``s`` consecutive frames into one row (a free
    reshape), which makes the layer a stride-1 one over ``s * C`` channels. The output is
    the (B, T', C') rows seen as (B, C', T'), so the next layer's ``transpose`` costs
    nothing. The previous form unfolded every frame's taps into a copied (B * T', C * k)
    matrix and transposed every layer's input: 37 % of the generator's time in copies,
    where the products were 28 %. This form: 1.3-1.9x faster for 8 to 64 words, the
    same for one (``bench/bench_models.py``, its baseline rows)."""

    def tap_weights(self) -> torch.Tensor:
        """The weight as (taps / stride, stride * C, C') products, made once per weight
        version (inference weights do not change; a load or an optimiser step bumps it)."""
        key = (self.weight.data_ptr(), self.weight._version)
        cached = getattr(self, "_tap_weights", None)
        if cached is None or cached[0] != key:
            (k,), (s,) = self.kernel_size, self.stride
            groups = -(-k // s)
            w = F.pad(self.weight.detach(), (0, groups * s - k))  # zero taps up to whole groups
            w = w.reshape(self.out_channels, self.in_channels, groups, s).permute(2, 3, 1, 0)
            cached = (key, w.reshape(groups, s * self.in_channels, self.out_channels).contiguous())
            self._tap_weights = cached
        return cached[1]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        (k,), (s,), (pad,), (dilation,) = self.kernel_size, self.stride, self.padding, self.dilation
        if self.groups != 1 or dilation != 1:
            raise ValueError("RowConv1d computes plain convolutions only (groups 1, dilation 1)")
        b, c, length = x.shape
        taps = self.tap_weights()
        groups = taps.shape[0]
        frames = (length + 2 * pad - k) // s + 1
        grouped = frames - 1 + groups  # rows of s frames per word that the taps read
        # The padded frames in one gather (a copy either way; one operation, where a
        # concatenation of edge views took five: about a fifth of a one-word call here).
        frame_index = _padded_frame_index(length, pad, grouped * s, self.padding_mode, x.device)
        rows = x.transpose(1, 2)  # (B, T, C)
        if self.padding_mode != "replicate" and grouped * s > length:
            rows = F.pad(rows, (0, 0, 0, 1))  # frame `length`: the zero the index points at
        rows = rows.index_select(1, frame_index).reshape(b * grouped, s * c)
        n = b * grouped - groups + 1  # the last tap's shifted rows must stay inside
        out = torch.empty(b * grouped, self.out_channels, dtype=x.dtype, device=x.device)
        if self.bias is None:
            torch.mm(rows[:n], taps[0], out=out[:n])
        else:
            torch.addmm(self.bias, rows[:n], taps[0], out=out[:n])
        for q in range(1, groups):
            out[:n].addmm_(rows[q:q + n], taps[q])
        return out.view(b, grouped, self.out_channels)[:, :frames].transpose(1, 2)


class RowLinear(nn.Linear):
    """A ``Linear`` as a product and a sum over its inputs, never a matrix-vector kernel
    (the inputs are a style code's 16 numbers: the cost is nothing)."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out = (x.unsqueeze(-1) * self.weight.t()).sum(-2)
        return out if self.bias is None else out + self.bias


INFERENCE_FORMS: dict[type, type] = {nn.Conv1d: RowConv1d, nn.Linear: RowLinear}  # training layer -> form


def batch_invariant(model: nn.Module) -> nn.Module:
    """``model`` with each layer in ``INFERENCE_FORMS`` computed in its inference form
    (the same weights; for a live restyler, whose words must not depend on their batch)."""
    return _swap_forms(model, INFERENCE_FORMS)


def training_forms(model: nn.Module) -> nn.Module:
    """A copy of ``model`` with the layers the trainer uses (a benchmark's baseline, a
    test's known-bad case)."""
    return copy_with_forms(model, {form: base for base, form in INFERENCE_FORMS.items()})


def copy_with_forms(model: nn.Module, forms: dict[type, type]) -> nn.Module:
    """A copy of ``model`` with each layer of a type in ``forms`` computed in the form it
    maps to (the same weights)."""
    return _swap_forms(copy.deepcopy(model), forms)


def _swap_forms(model: nn.Module, forms: dict) -> nn.Module:
    for module in model.modules():
        form = forms.get(type(module))
        if form is not None:
            module.__class__ = form  # the subclass adds no state: the weights stay as they are
    return model


def patch_discriminator(cfg: NetworkConfig, heads: int = 1) -> nn.Sequential:
    """The LSGAN patch discriminator's layers over (pose, velocity) channels, with ``heads``
    output channels (one per style for the multi-style model)."""
    f, h = cfg.features, cfg.d_hidden
    return nn.Sequential(
        nn.Conv1d(2 * f, h, 4, stride=2, padding=1), nn.LeakyReLU(0.2),
        nn.Conv1d(h, 2 * h, 4, stride=2, padding=1), nn.LeakyReLU(0.2),
        nn.Conv1d(2 * h, 2 * h, 3, padding=1), nn.LeakyReLU(0.2),
        nn.Conv1d(2 * h, heads, 3, padding=1),
    )


class Discriminator(nn.Module):
    def __init__(self, cfg: NetworkConfig):
        super().__init__()
        self.velocity_scale = cfg.d_velocity_scale
        self.net = patch_discriminator(cfg)

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
