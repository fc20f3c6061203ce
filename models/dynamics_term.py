"""The dynamics term of the multi-style model (``train --styles all --lambda-gram W``):
seed 004's Gram-matrix dynamics style, read against each style's own motion of the same
action.

Why: the multistyle model's restyled runs read as the target style in 3-21 % of windows
for every target (walks, raises and waves 75-100 % towards masculine), and the judges
that see only velocities read 36-37 % of its windows as the target (the mean over six
targets). Real masculine runs read as masculine 91 % of the time, so the style of a run is
there to learn; the generator does not learn it. The pair recipe's Gram term (``losses.gram_loss``) compared a
batch's generated words with the batch's real words of the target, whatever their actions:
measured noisy and unhelpful (MODEL_CARD.md: 59 % against 81 % for the same seed).

What it is: for every style s and action a, the mean velocity Gram matrix
(``losses.velocity_gram``: which channels move together and how strongly, whatever the
timing) of all of style s's training words of action a, computed once before training.
A batch's restyles are grouped by (target style, input action); each group's mean Gram
is held against its table entry, squared, relative to the table's mean square, so the
weight does not depend on the representation's scale. A restyled run towards elderly is
asked to move as elderly runs move, not as the average elderly word does.

Measured (MODEL_CARD.md, "A dynamics term per action"): at weight 1 the six targets' mean on
the worst judge rose in every pair of runs and the dynamics judges read more, but runs
still read as normal runs towards every target but exhausted.
"""

from __future__ import annotations

import torch

from .losses import velocity_gram

CHUNK = 512  # words per Gram computation when building the table


class ActionDynamics:
    """The term for a batch of channel words: 0 when every (target, action) group's mean
    Gram equals its style's and action's, 1 when they differ as much as the table's
    entries are large."""

    def __init__(self, words: list[torch.Tensor], actions: list[torch.Tensor], classes: int, device):
        """``words``: each style's training words in channels (N, F, T), in ``STYLES``
        order, and ``actions`` their actions (N,) (indices below ``classes``)."""
        styles, features = len(words), words[0].shape[1]
        sums = torch.zeros(styles * classes, features, features, dtype=torch.float64)
        counts = torch.zeros(styles * classes, dtype=torch.float64)
        with torch.no_grad():
            for k, (w, a) in enumerate(zip(words, actions)):
                for i in range(0, len(w), CHUNK):
                    g = velocity_gram(w[i:i + CHUNK].to(device)).double().cpu()
                    group = k * classes + a[i:i + CHUNK]
                    sums.index_add_(0, group, g)  # on the CPU, once: deterministic
                    counts += torch.bincount(group, minlength=styles * classes).double()
        self.present = (counts > 0).to(device)  # (S*A,): a subset of the data may lack a pair
        table = (sums / counts.clamp(min=1)[:, None, None]).float()
        self.scale = float((table[counts > 0] ** 2).mean())
        self.table, self.classes, self.groups = table.to(device), classes, styles * classes

    def __call__(self, restyled: torch.Tensor, target: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        """``restyled``: the generator's words in channels (B, F, T); ``target``, ``action``:
        each word's target style and its input's action, indices (B,)."""
        g = velocity_gram(restyled).flatten(1)  # (B, F*F)
        # Group sums as a product with a one-hot matrix: index_add_ is not deterministic on CUDA.
        onehot = torch.nn.functional.one_hot(target * self.classes + action, self.groups).to(g.dtype)
        counts = onehot.sum(0)
        used = (counts > 0) & self.present
        means = (onehot.T @ g)[used] / counts[used, None]
        return ((means - self.table.flatten(1)[used]) ** 2).mean() / self.scale
