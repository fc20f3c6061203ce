"""The style loss (``models/style_target.py``, ``train --lambda-style``)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from stylecast.models import style_target
from stylecast.models.data import WordSet
from stylecast.models.style_target import StyleWords, load_style_words
from stylecast.models.styles import STYLES
from stylecast.models.train import Trainer
from stylecast.motion.errors import UserError

from .test_models import _tiny_cfg, synthetic_words

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _style_words(n: int, seed: int, style: int) -> np.ndarray:
    """Synthetic words of one of seven styles: each style holds its own bone bent by 60°."""
    q = synthetic_words(n, seed, amplitude=0.2)
    bone = 4 + 2 * style
    bent = Rotation.from_quat(q[:, :, bone].reshape(-1, 4)) * Rotation.from_euler("x", 60, degrees=True)
    q[:, :, bone] = bent.as_quat().reshape(n, 60, 4)
    return q


def _styles(train: int, val: int) -> StyleWords:
    return StyleWords(STYLES, {s: _style_words(train, 10 + i, i) for i, s in enumerate(STYLES)},
                      {s: _style_words(val, 20 + i, i) for i, s in enumerate(STYLES)})


def test_the_style_loss_knows_the_target_leaves_the_gan_stream_alone_and_reaches_the_generators():
    styles = _styles(48, 8)
    a, b = styles.train["normal"][:8], styles.train["exhausted"][:8]
    off = Trainer(_tiny_cfg(), a, b, a[:4], b[:4], device="cpu")
    on = Trainer(_tiny_cfg(lambda_style=1.0), a, b, a[:4], b[:4], device="cpu", styles=styles)
    start_off, start_on = off.model.state_dict(), on.model.state_dict()
    assert all(torch.equal(start_off[k], start_on[k]) for k in start_off)  # nothing drawn from the GAN's stream
    # The known answer: real exhausted words cost G_a2b little, normal ones (an identity restyle) a lot.
    to_exhausted = on.style_targets[0]
    assert on.style_judge.classes[int(to_exhausted)] == "exhausted"
    real = on.style_judge.loss(on._channels(styles.val["exhausted"]), to_exhausted.expand(8)).item()
    unchanged = on.style_judge.loss(on._channels(styles.val["normal"]), to_exhausted.expand(8)).item()
    assert real < 0.5 < 2.0 < unchanged
    row_off, row_on = off.run_epoch(), on.run_epoch()
    assert row_off["style_a2b"] == 0.0 and row_on["style_a2b"] > 0.0 and row_on["style_b2a"] > 0.0
    after_off, after_on = off.model.state_dict(), on.model.state_dict()
    assert any(k.startswith("G_") and not torch.equal(after_off[k], after_on[k]) for k in after_off)
    assert 0.0 <= on.style_judge.accuracy["val"] <= 1.0
    assert not any(p.requires_grad for p in on.style_judge.net.parameters())


def test_the_style_loss_without_every_style_is_refused_in_one_sentence():
    a = synthetic_words(8, 1)
    with pytest.raises(UserError, match="needs training words of every style") as e:
        Trainer(_tiny_cfg(lambda_style=1.0), a, a, device="cpu")
    assert "\n" not in str(e.value)


def test_style_words_keep_the_pair_and_read_a_few_words_of_every_other_style(bandai_root, tmp_path, monkeypatch):
    monkeypatch.setattr(style_target, "OTHER_STYLE_WORDS", 3)
    pair = {(s, split): WordSet(s, synthetic_words(2, 0), np.zeros(2, np.int64), [])
            for s in ("normal", "exhausted") for split in ("train", "val")}
    styles = load_style_words(_tiny_cfg(val_words=2), pair, bandai_root / "dataset-2" / "data", tmp_path / "cache",
                              progress=False)
    assert styles.classes == STYLES
    assert styles.train["normal"] is pair[("normal", "train")].words
    for s in set(STYLES) - {"normal", "exhausted"}:
        assert 1 <= len(styles.train[s]) <= 3 and 1 <= len(styles.val[s]) <= 2
        assert styles.train[s].shape[1:] == (60, 22, 4)
    words, labels = styles.labelled("train")
    assert len(labels) == sum(len(w) for w in words) and set(labels) == set(range(7))

