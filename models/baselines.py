"""The posture-only baseline: the cheapest thing that could pass for a style.

Each bone's mean rotation over the training words of the source and of the target style
(heading removed, as the generators see words) gives a per-bone offset
``delta_j = mean_source_j^-1 * mean_target_j``; the baseline applies it to every frame,
``q_out = q_in * delta_j``, so a frame posed exactly like the source's average pose comes
out posed like the target's. It changes nothing in time: no dynamics, no jitter. A model
has to beat it on style to be worth its cost.
"""

from __future__ import annotations

import numpy as np

from stylecast.motion import rotations as rot

from . import data as D
from . import representation as R


class PostureRestyler:
    def __init__(self, delta: np.ndarray):
        self.delta = np.asarray(delta, dtype=np.float64)  # (J, 4)

    @classmethod
    def from_data(cls, source: str, target: str, files: list, cache_dir=None, per_style: int | None = None):
        means = []
        for style in (source, target):
            motions = D.load_motions(D.files_for_style(files, style, "train")[:per_style], cache_dir)
            words = D.build_wordset(motions, style, hop=D.WORD_LENGTH).words
            means.append(R.mean_reference(words))
        return cls(rot.multiply(rot.inverse(means[0]), means[1]))

    def restyle_words(self, words: np.ndarray) -> np.ndarray:
        flat, yaw = R.remove_heading(np.asarray(words, dtype=np.float64))
        out = R.restore_heading(rot.multiply(flat, self.delta), yaw)
        return np.where(np.sum(out * words, axis=-1, keepdims=True) < 0, -out, out)
