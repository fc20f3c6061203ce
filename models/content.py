"""Frozen classifiers the generators answer to. The action-content loss (``train
--lambda-action``): a restyle must keep what the performer is doing. The style loss (``train
--lambda-style``, ``style_target.py``) uses the same classifier over all seven styles.

Why: the CycleGAN's losses never see the action. The cycle only asks that a way back
exists, so the generator may move a one-hand raise towards a wave as long as its partner
moves it back. The evaluation's confusion rows show it doing so: the pair models push raises
and waves of one hand towards one generic tired arm (raise-up-right-hand taken for
wave-right-hand in 42-64 % of windows; MODEL_CARD.md).

What it is: an action classifier over the generator's own feature space (the
representation's channels and their per-second differences, so it is differentiable
through the generator without forward kinematics), trained on the training words of the
pair's two styles before the GAN starts, then frozen. The generators pay its
cross-entropy on their restyled words against the action of the words they were given.

Deliberately not the evaluation's judge (``judges.py``): other inputs (joint rotations in the
representation, not world joint positions), only the pair's two styles, another seed. A model
that learned to satisfy this classifier without keeping the action would still be caught by
the judge, and by the independent instruments that score the shipped models.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from .classifier import _net
from .losses import FPS
from .networks import from_channels, to_channels
from .representation_torch import DTYPE, TorchRepresentation, quat_to_matrix

CM = 100.0  # PositionView's metres to the metrics' centimetres

EPOCHS = 10
BATCH = 64
LR = 2e-3
ACTION_SALT = 7919  # a classifier's weights come from (seed + salt), away from the GAN's stream


def _with_velocity(x: torch.Tensor) -> torch.Tensor:
    """(B, F, T) channel words -> (B, 2F, T): values and per-second differences."""
    v = torch.diff(x, dim=2, prepend=x[:, :, :1]) * FPS
    return torch.cat([x, v], dim=1)


class PositionView:
    """Channel words (B, J*C, T) -> joint positions (B, J*3, T) in metres, relative to the
    hips, by forward kinematics on ``skeleton``: what the evaluation's judges see
    (``judges.judge_windows``, less the root's travel, which no word carries), differentiable,
    so the generators answer to a classifier of that view (``train --action-view positions``).

    Why: the channels classifier is satisfied while the judges are not. With it at weight
    0.25 the default keeps raise-up-left-hand in 86 % of windows and walk-turn-left in 69 %
    to the judges (the input: 100 % and 80 %); the judges see hands and feet in space, where
    a small change of a shoulder's angle is a large change of the hand's path."""

    def __init__(self, representation, skeleton, device, joints: tuple[int, ...] | None = None):
        """``joints``: only these joints' positions (in this order), by forward kinematics over
        their ancestors alone; None: every joint."""
        self.rep = TorchRepresentation(representation, device)
        self.parents = tuple(skeleton.parents)
        self.offsets = torch.as_tensor(np.asarray(skeleton.offsets) / 100.0, dtype=DTYPE, device=device)
        self.joints = tuple(range(len(self.parents))) if joints is None else tuple(joints)
        needed = set()
        for j in self.joints:
            while j >= 0 and j not in needed:
                needed.add(j)
                j = self.parents[j]
        self._chain = sorted(needed)  # parents come before children in the skeleton's order
        self.features = 3 * len(self.joints)

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        local = quat_to_matrix(self.rep.decode(from_channels(x, len(self.parents))))  # (B, T, J, 3, 3)
        world, positions = {}, {}
        for j in self._chain:  # topological order, each step batched over words and frames
            p = self.parents[j]
            if p < 0:
                world[j] = local[..., j, :, :]
                positions[j] = torch.zeros_like(local[..., j, :, 0])
            else:
                world[j] = world[p] @ local[..., j, :, :]
                positions[j] = positions[p] + world[p] @ self.offsets[j]
        return to_channels(torch.stack([positions[j] for j in self.joints], dim=-2).to(torch.float32))


@dataclass
class ActionLabels:
    """The action of every word a trainer is given, {style: indices into ``classes``}, for
    the training and the held-out words."""

    classes: list[str]
    train: dict
    val: dict

    @classmethod
    def of(cls, sets: dict) -> "ActionLabels":
        """From word sets keyed (style, "train" | "val") (``data.WordSet``), as the pair's
        ``train.load_training_words`` and the multistyle ``load_all_styles`` read them."""
        classes = sorted({f.action for ws in sets.values() for f in ws.files})
        split = lambda name: {style: action_labels(ws, classes) for (style, s), ws in sets.items() if s == name}
        return cls(classes, split("train"), split("val"))


def action_labels(wordset, classes: list[str]) -> np.ndarray:
    """Each word's action as an index into ``classes`` (``data.WordSet``)."""
    actions = np.array([classes.index(f.action) for f in wordset.files], dtype=np.int64)
    return actions[wordset.file_index] if len(wordset) else np.zeros(0, np.int64)


class FrozenClassifier:
    """A classifier of channel words, trained once and then frozen, and the loss the
    generators pay on it."""

    def __init__(self, classes: list[str], features: int, seed: int, salt: int = ACTION_SALT, view=None):
        """``view``: a function of channel words the classifier sees instead of them (a
        ``PositionView``; ``features`` is then its width), or None."""
        # fork_rng: building and training the classifier draws nothing from the GAN's random
        # stream, so a run with the loss off is bit-identical to one without this module.
        self.seed, self.salt = seed, salt
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed + salt)
            self.net = _net(features, len(classes))
        self.classes = list(classes)
        self.accuracy: dict[str, float] = {}
        self.view = view or (lambda x: x)

    def _logits(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(_with_velocity(self.view(x)))

    def fit(self, x: torch.Tensor, y: np.ndarray, device) -> "FrozenClassifier":
        """``x``: (N, F, T) channel words on the CPU, ``y``: their class indices."""
        rng = np.random.default_rng((self.seed, self.salt))
        counts = np.bincount(y, minlength=len(self.classes)).astype(np.float64)
        weight = torch.tensor(counts.sum() / np.maximum(counts, 1) / len(self.classes), dtype=torch.float32)
        loss_fn = nn.CrossEntropyLoss(weight=weight.to(device))
        self.net.to(device).train()
        opt = torch.optim.Adam(self.net.parameters(), lr=LR, weight_decay=1e-4)
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, EPOCHS)
        labels = torch.from_numpy(np.asarray(y, np.int64))
        with torch.random.fork_rng(devices=[]):  # dropout draws, kept off the GAN's stream too
            torch.manual_seed(self.seed + self.salt)
            for _ in range(EPOCHS):
                order = rng.permutation(len(x))
                for i in range(0, len(order), BATCH):
                    idx = torch.from_numpy(order[i:i + BATCH])
                    opt.zero_grad(set_to_none=True)
                    loss_fn(self._logits(x[idx].to(device)), labels[idx].to(device)).backward()
                    opt.step()
                sched.step()
        self.net.eval()
        for p in self.net.parameters():
            p.requires_grad_(False)
        return self

    def predict(self, x: torch.Tensor, device, batch: int = 512) -> np.ndarray:
        with torch.no_grad():
            return np.concatenate([self._logits(x[i:i + batch].to(device)).argmax(1).cpu().numpy()
                                   for i in range(0, len(x), batch)]) if len(x) else np.zeros(0, np.int64)

    def score(self, name: str, x: torch.Tensor, y: np.ndarray, device) -> float:
        """Accuracy on real words, kept in ``accuracy[name]``: the loss means something only
        if the classifier knows the classes of real held-out words."""
        self.accuracy[name] = float(np.mean(self.predict(x, device) == y)) if len(y) else float("nan")
        return self.accuracy[name]

    def loss(self, generated: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
        """Cross-entropy of the restyled words (B, F, T) against ``labels`` (B,): the input
        words' actions, or the target style."""
        return nn.functional.cross_entropy(self._logits(generated), labels)
