"""Small word classifiers for evaluation: style (which of the seven styles?) and content
(which of the 10 actions?). Trained on real training-split words only, judged on
held-out files. They are measuring instruments, deliberately unlike the discriminators:
a 1-D conv net with global average pooling over time, trained with cross-entropy. The
pooled layer (``embed``) is the feature space of the Frechet motion distance.
"""

from __future__ import annotations

import numpy as np


def _net(features: int, classes: int, hidden: int = 64):
    """The convolutional classifier: three 5-frame convolutions, pooled over time."""
    from torch import nn

    return nn.Sequential(
        nn.Conv1d(2 * features, hidden, 5, padding=2), nn.ReLU(),
        nn.Conv1d(hidden, hidden, 5, padding=2, stride=2), nn.ReLU(),
        nn.Conv1d(hidden, hidden, 5, padding=2, stride=2), nn.ReLU(),
        nn.AdaptiveAvgPool1d(1), nn.Flatten(), nn.Dropout(0.2), nn.Linear(hidden, classes),
    )


def _recurrent_net(features: int, classes: int, hidden: int = 64):
    """A bidirectional GRU over the frames, its states averaged over time: a judge of
    another design, whose quirks are not the convolutions' (``judges.py``)."""
    from torch import nn

    from .recurrent import MeanGRU

    return nn.Sequential(MeanGRU(2 * features, hidden), nn.Dropout(0.2), nn.Linear(2 * hidden, classes))


# The judges' designs, by name (``WordClassifier(design=...)``). Every design ends in Dropout
# and a Linear head over pooled features: ``embed`` reads the features before them.
DESIGNS = {"conv": _net, "gru": _recurrent_net}


def word_inputs(x, velocity_only: bool = False):
    """Features (N, T, J, C), numpy or a float32 tensor on any device -> (N, 2*J*C, T):
    poses and per-second velocities (with ``velocity_only`` the pose half is zeroed, so
    only the dynamics can be judged)."""
    import torch

    t = x if isinstance(x, torch.Tensor) else torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32))
    n, T = t.shape[:2]
    t = t.reshape(n, T, -1).transpose(1, 2)
    v = torch.diff(t, dim=2, prepend=t[:, :, :1]) * 60.0
    return torch.cat([torch.zeros_like(t) if velocity_only else t, v], dim=1)


class WordClassifier:
    def __init__(self, classes: list[str], features: int, seed: int = 0, velocity_only: bool = False,
                 design: str = "conv"):
        import torch

        torch.manual_seed(seed)
        self.classes = list(classes)
        self.net = DESIGNS[design](features, len(classes))
        self.seed, self.design = seed, design
        self.velocity_only = velocity_only

    def fit(self, x: np.ndarray, y: np.ndarray, epochs: int = 12, batch: int = 64, lr: float = 2e-3) -> "WordClassifier":
        import torch
        from torch import nn

        rng = np.random.default_rng(self.seed)
        # Balance the classes: every class contributes the same weight to the loss.
        counts = np.bincount(y, minlength=len(self.classes)).astype(np.float64)
        weight = torch.tensor(counts.sum() / np.maximum(counts, 1) / len(self.classes), dtype=torch.float32)
        loss_fn = nn.CrossEntropyLoss(weight=weight)
        opt = torch.optim.Adam(self.net.parameters(), lr=lr, weight_decay=1e-4)
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, epochs)
        xt, yt = word_inputs(x, self.velocity_only), torch.from_numpy(np.asarray(y, dtype=np.int64))
        self.net.train()
        for _ in range(epochs):
            order = rng.permutation(len(xt))
            for i in range(0, len(order), batch):
                idx = torch.from_numpy(order[i:i + batch])
                opt.zero_grad()
                loss_fn(self.net(xt[idx]), yt[idx]).backward()
                opt.step()
            sched.step()
        self.net.eval()
        with torch.no_grad():
            for parameter in self.net.parameters():
                parameter.copy_(torch.from_numpy(flush_subnormals(parameter.detach().numpy())))
        return self

    def predict(self, x: np.ndarray, batch: int = 512) -> np.ndarray:
        if len(x) == 0:
            return np.zeros(0, dtype=int)
        return self.probabilities(x, batch).argmax(axis=1)

    def embed(self, x: np.ndarray, batch: int = 512) -> np.ndarray:
        """Penultimate features (N, pooled width): the pooled output before the head."""
        import torch

        trunk = self.net[:-2]  # drop Dropout and the Linear head
        out = []
        with torch.no_grad():
            for i in range(0, len(x), batch):
                out.append(trunk(word_inputs(x[i:i + batch], self.velocity_only)).numpy())
        return np.concatenate(out) if out else np.zeros((0, self.net[-1].in_features))

    def probabilities(self, x: np.ndarray, batch: int = 512) -> np.ndarray:
        import torch

        out = []
        with torch.no_grad():
            for i in range(0, len(x), batch):
                out.append(torch.softmax(self.net(word_inputs(x[i:i + batch], self.velocity_only)), dim=1).numpy())
        return np.concatenate(out) if out else np.zeros((0, len(self.classes)))

    def accuracy(self, x: np.ndarray, y: np.ndarray) -> float:
        return float(np.mean(self.predict(x) == np.asarray(y))) if len(x) else float("nan")


def flush_subnormals(weights: np.ndarray) -> np.ndarray:
    """``weights`` with their subnormal floats set to zero, as ``WordClassifier.fit`` leaves
    its network. The weight decay leaves the weights of channels that stopped learning
    decaying towards zero, and x86 multiplies the subnormal ones (below 1.2e-38) slowly: a
    conv style judge fitted as ``stylecast eval`` fits them had 5,044, and read 2,523
    held-out windows (probabilities and features) in 15.9 CPU-s with them, 0.7 without; the
    style reader (2,017 of them) read 64 words in 40 ms with them, 5.3 ms without. Both
    gave the same bits either way: each such weight is far below half a unit in the last
    place of any sum it enters (scratch measures, Intel Xeon VM, 2026-11-29)."""
    weights = np.array(weights)
    weights[np.abs(weights) < np.finfo(weights.dtype).tiny] = 0
    return weights
