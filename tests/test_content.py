"""The action-content loss (``models/content.py``, ``train --lambda-action``)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from stylecast.cli import main
from stylecast.models.content import ActionLabels, FrozenClassifier
from stylecast.models.train import Trainer
from stylecast.motion.errors import UserError

from .test_models import _tiny_cfg, synthetic_words

pytestmark = pytest.mark.usefixtures("one_torch_thread")

F, T = 66, 60  # 22 bones x 3 Euler values, one word


def gesture_words(n: int, channel: int, seed: int) -> torch.Tensor:
    """(n, F, T) channel words: small noise everywhere and one channel swinging at 2 Hz,
    the channel standing for the limb that makes the gesture."""
    rng = np.random.default_rng(seed)
    x = rng.normal(scale=0.01, size=(n, F, T))
    phase = rng.uniform(0, 2 * np.pi, size=(n, 1))
    x[:, channel] += 0.3 * np.sin(2 * np.pi * 2 * np.arange(T) / 60 + phase)
    return torch.from_numpy(x.astype(np.float32))


def test_the_classifier_learns_the_gestures_and_its_loss_rises_when_the_gesture_changes():
    content = FrozenClassifier(["raise", "wave"], F, seed=0)
    x = torch.cat([gesture_words(128, 10, 1), gesture_words(128, 40, 2)])
    y = np.repeat([0, 1], 128)
    content.fit(x, y, "cpu")
    held_out = torch.cat([gesture_words(16, 10, 3), gesture_words(16, 40, 4)])
    assert content.score("held-out", held_out, np.repeat([0, 1], 16), "cpu") == 1.0
    raises = gesture_words(16, 10, 5)
    kept = content.loss(raises, torch.zeros(16, dtype=torch.long)).item()
    # The known-bad case: the restyle turned every raise into a wave.
    turned = content.loss(gesture_words(16, 40, 6), torch.zeros(16, dtype=torch.long)).item()
    assert kept < 0.01 and turned > 5.0
    assert not any(p.requires_grad for p in content.net.parameters())  # frozen: only the generator learns


def _labels(n_a: int, n_b: int) -> ActionLabels:
    a, b = np.arange(n_a) % 2, np.arange(n_b) % 2
    return ActionLabels(["raise", "wave"], a, b, a[:4], b[:4])


def test_the_loss_leaves_the_gan_stream_alone_and_reaches_the_generators():
    a, b = synthetic_words(8, 1), synthetic_words(8, 2)
    off = Trainer(_tiny_cfg(), a, b, a[:4], b[:4], device="cpu")
    on = Trainer(_tiny_cfg(lambda_action=1.0), a, b, a[:4], b[:4], device="cpu", actions=_labels(8, 8))
    start_off, start_on = off.model.state_dict(), on.model.state_dict()
    # Building and fitting the classifier drew nothing from the GAN's random stream.
    assert all(torch.equal(start_off[k], start_on[k]) for k in start_off)
    row_off, row_on = off.run_epoch(), on.run_epoch()
    assert row_off["action_a2b"] == 0.0 and row_on["action_a2b"] > 0.0 and row_on["action_b2a"] > 0.0
    after_off, after_on = off.model.state_dict(), on.model.state_dict()
    changed = [k for k in after_off if k.startswith("G_") and not torch.equal(after_off[k], after_on[k])]
    assert changed  # the loss's gradient reaches the generators
    assert "val" in on.content.accuracy


def test_the_loss_without_actions_is_refused_in_one_sentence():
    a = synthetic_words(8, 1)
    with pytest.raises(UserError, match="needs the action of every training word") as e:
        Trainer(_tiny_cfg(lambda_action=1.0), a, a, device="cpu")
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("args, message", [
    (["--lambda-action", "-1"], "--lambda-action must be 0 or more"),
    (["--lambda-action", "1", "--styles", "all"], "--lambda-action is for a pair model"),
])
def test_bad_lambda_action_is_refused_before_any_data_is_read(tmp_path, capsys, args, message):
    code = main(["train", "--out", str(tmp_path / "run"), "--data", str(tmp_path / "nowhere"), *args])
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1
