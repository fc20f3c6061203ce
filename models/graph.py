"""The skeleton-graph generator (seed 003): the multi-style G(x, s) with its convolutions
over the humanoid's bone graph as well as over time (``MultiStyleConfig.graph_channels``
> 0; ``stylecast train --styles all --generator graph``).

The temporal generator (``multistyle.MultiStyleGenerator``) treats a word as 66 channels
(22 bones x 3 features) and mixes all of them in its first layer: it has to learn from
data which bones move together. Here every bone keeps its own feature vector of
``graph_channels`` values through the network (tensors (B, J, H, T): bone, channel, time), and one
layer only mixes a bone with its neighbours in the skeleton, as in ST-GCN (Yan et al.
2018), which seed 003 builds on:

- ``GraphConv``: three partitions of the neighbourhood (the bone itself, its parent, its
  children), each with its own 1x1 weights, summed over the humanoid's fixed adjacency
  (``skeleton_adjacency``, columns normalised) plus a learnt one (zero at the start, as in
  2s-AGCN), so links the skeleton lacks (left hand with right hand, hand with foot for
  an arm swing) can be learnt.
- Temporal convolutions are shared by all bones (1-D, run on (B*J, H, T)); a learnt
  per-bone embedding added after the stem tells the shared weights which bone they work
  on.
- The style code enters through AdaIN on each bone's channels (``conditioning.AdaIN`` over
  the H*J channels), so a style can scale and shift each bone's features its own way.

The rest is the temporal generator's: stem, strided conv to half rate, residual blocks,
fixed linear upsampling, fuse with the full-rate skip, zero-initialised head (per bone,
H -> C) giving a correction that ``networks.apply_correction`` projects on the cubic
B-spline and puts on the input: the identity map at the start, and no jitter whatever it
learns. Same forward signature, so the trainer, the restyler and the daemon take either.

Measured against the temporal generator (two seeds, ``models/checkpoints/MODEL_CARD.md``):
weaker on every figure of ``stylecast eval`` and 3.7x its inference cost, so the shipped
multi-style model keeps the temporal one.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from stylecast.motion.humanoid import HUMANOID_PARENTS

from .conditioning import AdaIN, StyleCodes
from .networks import apply_correction, register_fixed_matrices, zero_head

PARTITIONS = 3  # the bone itself, its parent, its children


def skeleton_adjacency(parents: tuple[int, ...] = HUMANOID_PARENTS) -> np.ndarray:
    """(3, J, J) adjacency A[k, i, j]: how much bone i feeds bone j in partition k (self,
    from the parent, from the children); each column of a partition sums to 1 or 0."""
    j = len(parents)
    a = np.zeros((PARTITIONS, j, j))
    a[0] = np.eye(j)
    for child, parent in enumerate(parents):
        if parent >= 0:
            a[1, parent, child] = 1.0  # a child hears its parent
            a[2, child, parent] = 1.0  # a parent hears its children
    sums = a.sum(axis=1, keepdims=True)
    return a / np.where(sums > 0, sums, 1.0)


def _time_conv(cin: int, cout: int, k: int, stride: int = 1, padding: int | None = None) -> nn.Conv1d:
    """A convolution over time only, shared by every bone (run on (B*J, cin, T))."""
    pad = k // 2 if padding is None else padding
    return nn.Conv1d(cin, cout, k, stride=stride, padding=pad, padding_mode="replicate")


def per_bone(conv: nn.Module, x: torch.Tensor) -> torch.Tensor:
    """Apply a 1-D layer to every bone's channels: (B, J, H, T) -> (B, J, H', T')."""
    b, j = x.shape[:2]
    y = conv(x.reshape(b * j, *x.shape[2:]))
    return y.reshape(b, j, *y.shape[1:])


class GraphConv(nn.Module):
    """(B, J, cin, T) -> (B, J, cout, T): each bone mixes with its skeleton neighbours.

    In the (bone, channel, time) layout without copies: first one matrix product with
    the adjacency over bones, its partitions stacked bone-major so that the result reads
    as (B, J, K*cin, T), then one channel mix (K*cin -> cout, a 1x1 conv per bone). An
    einsum over (B, K, C, J, T), or the channel mix as a broadcast matrix product, made
    the whole training step about 12 % slower on this machine (copies for the permutes
    and the broadcast)."""

    def __init__(self, cin: int, cout: int, adjacency: np.ndarray):
        super().__init__()
        self.register_buffer("adjacency", torch.from_numpy(adjacency.astype(np.float32)), persistent=False)
        self.learnt = nn.Parameter(torch.zeros(adjacency.shape))
        self.mix = nn.Conv1d(PARTITIONS * cin, cout, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, j, c, t = x.shape
        k = PARTITIONS
        a = (self.adjacency + self.learnt).permute(2, 0, 1).reshape(j * k, j)  # rows (bone out, partition)
        gathered = (a @ x.reshape(b, j, c * t)).reshape(b, j, k * c, t)
        return per_bone(self.mix, gathered)


class GraphBlock(nn.Module):
    """Residual: graph conv -> AdaIN -> act -> temporal conv -> AdaIN, added to the input."""

    def __init__(self, ch: int, joints: int, adjacency: np.ndarray, code_dim: int):
        super().__init__()
        self.graph = GraphConv(ch, ch, adjacency)
        self.n1 = AdaIN(ch * joints, code_dim)
        self.time = _time_conv(ch, ch, 3)
        self.n2 = AdaIN(ch * joints, code_dim)
        self.act = nn.LeakyReLU(0.2)

    @staticmethod
    def _norm(norm: AdaIN, x: torch.Tensor, code: torch.Tensor) -> torch.Tensor:
        b, j, c, t = x.shape
        return norm(x.reshape(b, j * c, t), code).reshape(b, j, c, t)

    def forward(self, x: torch.Tensor, code: torch.Tensor) -> torch.Tensor:
        y = self.act(self._norm(self.n1, self.graph(x), code))
        return x + self._norm(self.n2, per_bone(self.time, y), code)


class GraphStyleGenerator(nn.Module):
    """G(x, s) over the bone graph; ``forward`` as ``MultiStyleGenerator.forward``. The
    layers are built in one fixed order, the order their weights draw from torch's
    generator: a seed gives the same network again."""

    def __init__(self, cfg, combine):
        """``cfg``: a ``multistyle.MultiStyleConfig`` with ``graph_channels`` > 0."""
        super().__init__()
        if not cfg.graph_channels:
            raise ValueError("the graph generator needs graph_channels > 0")
        h, c, j = cfg.graph_channels, cfg.channels, cfg.joints
        adjacency = skeleton_adjacency()
        if adjacency.shape[-1] != j:
            raise ValueError(f"the graph generator works on the {adjacency.shape[-1]}-bone humanoid, not {j} bones")
        self.joints, self.channels = j, c
        self.combine = combine
        self.codes = StyleCodes(cfg.num_styles, cfg.code_dim)
        self.stem = GraphConv(c, h, adjacency)
        self.stem_time = _time_conv(h, h, cfg.g_kernel)
        self.joint_embedding = nn.Parameter(torch.zeros(1, j, h, 1))
        self.down = _time_conv(h, h, 4, stride=2, padding=1)
        self.blocks = nn.ModuleList([GraphBlock(h, j, adjacency, cfg.code_dim) for _ in range(cfg.g_blocks)])
        register_fixed_matrices(self, cfg)
        self.fuse = _time_conv(2 * h, h, 3)
        self.head = zero_head(h, c)
        self.act = nn.LeakyReLU(0.2)

    def forward(self, x: torch.Tensor, weights: torch.Tensor, intensity: torch.Tensor | None = None) -> torch.Tensor:
        """x (B, J*C, T); weights (B, S) style mix per word; intensity (B,) or None (= 1)."""
        b, _, t = x.shape
        code = self.codes(weights)
        bones = x.reshape(b, self.joints, self.channels, t)  # the channels are bone-major: a view
        skip = self.act(per_bone(self.stem_time, self.act(self.stem(bones))) + self.joint_embedding)
        y = self.act(per_bone(self.down, skip))
        for block in self.blocks:
            y = block(y, code)
        y = self.act(per_bone(self.fuse, torch.cat([y @ self.upsample, skip], dim=2)))
        delta = per_bone(self.head, y).reshape(b, self.joints * self.channels, t)
        scale = None if intensity is None else intensity.to(x.dtype).reshape(-1, 1, 1)
        return apply_correction(x, delta, self.smooth, scale, self.combine)
