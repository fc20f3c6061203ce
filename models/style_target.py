"""The style loss (``train --lambda-style``): a restyled word must read as the target style
among all seven, not merely as "not the source".

Why: the pair CycleGAN's discriminator only learns "real exhausted or restyled". Anything
it cannot tell from exhausted passes: the first shipped model's walks read as youthful, and
restyled walks and turns (seed 1 with the action loss) read as exhausted in only 40-74 % of
their windows (the rest mostly normal) while raises and waves do in all of them.

Measured (MODEL_CARD.md, "Action-content and style losses"): it does not work. The
classifier is satisfied within two epochs while the evaluation's judge reads fewer windows
as exhausted (seed 1: 80.7 % without, 58.9 % at weight 1). Kept as an off-by-default option.

What it is: StarGAN's domain-classification term with the classifier trained beforehand
and frozen (``content.FrozenClassifier``): a seven-style classifier over the generator's
feature space, trained on training words of every dataset-2 style before the GAN starts.
Each generator pays its cross-entropy against its target style.

Deliberately not the evaluation's style judge (``judges.py``): joint rotations in the
generator's representation instead of world joint positions, other words, another seed.
A generator that fooled this one without changing the style would still be caught there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import data as D
from .styles import STYLES

STYLE_SALT = 104729  # the style classifier's seed offset (content.ACTION_SALT is the action one's)
OTHER_STYLE_WORDS = 1024  # training words of each style outside the pair (spread over its takes)


@dataclass
class StyleWords:
    """Heading-free quaternion words (N, 60, J, 4) of every style, training and held out."""

    classes: tuple[str, ...]
    train: dict[str, np.ndarray]
    val: dict[str, np.ndarray]

    def labelled(self, split: str) -> tuple[list[np.ndarray], np.ndarray]:
        """(each style's words in ``classes`` order, their style indices)."""
        words = getattr(self, split)
        return ([words[s] for s in self.classes],
                np.concatenate([np.full(len(words[s]), i, np.int64) for i, s in enumerate(self.classes)]))


def load_style_words(cfg, sets: dict, data_dir=None, cache_dir=None, progress: bool = True) -> StyleWords:
    """The pair's own words (``train.load_training_words``'s ``sets``) and up to
    ``OTHER_STYLE_WORDS`` training words of each other style, ``cfg.val_words`` held out."""
    train, val = {}, {}
    for style in STYLES:
        if (style, "train") in sets:
            train[style], val[style] = sets[(style, "train")].words, sets[(style, "val")].words
            continue
        train[style] = D.load_wordset(style, "train", data_dir, cache_dir, cfg.hop,
                                      OTHER_STYLE_WORDS, progress).words
        val[style] = D.load_wordset(style, "val", data_dir, cache_dir, cfg.hop, cfg.val_words, progress).words
    return StyleWords(STYLES, train, val)
