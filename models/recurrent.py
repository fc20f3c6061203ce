"""The recurrent trunk of a judge (``classifier._recurrent_net``), a module of its own so
that torch is imported only when a judge is built, and a trained judge pickles."""

from __future__ import annotations

import torch
from torch import nn


class MeanGRU(nn.Module):
    """(N, C, T) channel words -> (N, 2 * hidden): a bidirectional GRU over the frames of
    a linear projection of the channels, its states averaged over time."""

    def __init__(self, channels: int, hidden: int):
        super().__init__()
        self.inp = nn.Linear(channels, hidden)
        self.gru = nn.GRU(hidden, hidden, batch_first=True, bidirectional=True)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        states, _ = self.gru(torch.relu(self.inp(x.transpose(1, 2))))
        return states.mean(dim=1)
