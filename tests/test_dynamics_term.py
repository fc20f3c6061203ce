"""The multistyle model's dynamics term (``models/dynamics_term.py``): each restyle's velocity
Gram matrix against its target style's own words of the same action."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from stylecast.models.content import ActionLabels
from stylecast.models.dynamics_term import ActionDynamics
from stylecast.models.losses import velocity_gram
from stylecast.models.networks import to_channels
from stylecast.models.styles import STYLES
from stylecast.models.train_multistyle import MultiStyleTrainer
from stylecast.motion.errors import UserError

from tests.test_multistyle import _tiny_cfg, _tiny_words

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _words_and_actions(n: int = 40, seed: int = 0):
    """Channel words (N, 4, 60) per style: each action a sine at its own rate, each style
    its own amplitude; actions alternate 0, 1."""
    rng = np.random.default_rng(seed)
    t = np.arange(60) / 60.0
    words, actions = [], []
    for k in range(3):
        a = np.arange(n) % 2
        rate = np.where(a == 0, 1.0, 3.0)[:, None, None]
        phase = rng.uniform(0, 2 * np.pi, (n, 4, 1))
        w = (0.2 + 0.2 * k) * np.sin(2 * np.pi * rate * t + phase) + 0.01 * rng.standard_normal((n, 4, 60))
        words.append(torch.tensor(w, dtype=torch.float32))
        actions.append(torch.from_numpy(a))
    return words, actions


def test_the_table_is_each_styles_and_actions_mean_gram():
    words, actions = _words_and_actions()
    term = ActionDynamics(words, actions, 2, "cpu")
    for s in range(3):
        for a in range(2):
            expected = velocity_gram(words[s][actions[s] == a]).mean(0)
            torch.testing.assert_close(term.table[s * 2 + a], expected, rtol=1e-5, atol=1e-6)


def test_real_words_read_low_on_their_own_style_and_high_on_another_or_another_action():
    words, actions = _words_and_actions()
    term = ActionDynamics(words, actions, 2, "cpu")
    x, a = words[1], actions[1]
    own = term(x, torch.full((len(x),), 1), a)
    assert float(own) < 1e-6  # the whole set is its own table entry
    # The known-bad cases: style 1's words said to be style 2 (larger swings) or style 0,
    # and its slow action's words said to be the fast one, all read far from their table.
    for wrong_style in (0, 2):
        assert float(term(x, torch.full((len(x),), wrong_style), a)) > 0.05
    assert float(term(x, torch.full((len(x),), 1), 1 - a)) > 0.5
    # Unseen words of the right style and action read near it: 20 words of a fresh draw.
    fresh, fresh_a = _words_and_actions(seed=1)
    near = float(term(fresh[1][:20], torch.full((20,), 1), fresh_a[1][:20]))
    assert near < 0.2 * float(term(fresh[1][:20], torch.full((20,), 2), fresh_a[1][:20]))


def test_its_gradient_moves_a_restyle_towards_its_target_styles_dynamics():
    words, actions = _words_and_actions()
    term = ActionDynamics(words, actions, 2, "cpu")
    x = words[0].clone().requires_grad_(True)  # style 0's words, asked to move as style 2's do
    target = torch.full((len(x),), 2)
    before = term(x, target, actions[0])
    before.backward()
    with torch.no_grad():
        after = term(x - 0.05 * x.grad / x.grad.abs().max() * x.abs().max(), target, actions[0])
    assert after.item() < before.item()


def test_the_multistyle_trainer_pays_it_when_asked_and_refuses_it_without_actions():
    words = _tiny_words()
    labels = {s: np.arange(len(w)) % 2 for s, w in words.items()}
    actions = ActionLabels(["raise", "wave"], labels, {s: v[:4] for s, v in labels.items()})
    off = MultiStyleTrainer(_tiny_cfg(), words, device="cpu")
    on = MultiStyleTrainer(_tiny_cfg(lambda_gram=1.0), words, device="cpu", actions=actions)
    start_off, start_on = off.model.state_dict(), on.model.state_dict()
    assert all(torch.equal(start_off[k], start_on[k]) for k in start_off)  # the same GAN at the start
    row_off, row_on = off.run_epoch(), on.run_epoch()
    assert row_off["gram"] == 0.0 and row_on["gram"] > 0.0
    assert on.dynamics.table.shape == (len(STYLES) * 2, *2 * [to_channels(on.words[0][:1]).shape[1]])
    with pytest.raises(UserError, match="--lambda-gram needs the action of every training word") as e:
        MultiStyleTrainer(_tiny_cfg(lambda_gram=1.0), words, device="cpu")
    assert "\n" not in str(e.value)


def test_a_config_saved_before_the_term_reads_as_without_it_and_one_saved_today_as_with_it():
    """What `--resume` compares a run against (`epoch_loop.read_train_state`): an old run
    must not read as having had the term, or resuming it would switch the term on."""
    from stylecast.models.train_multistyle import MultiStyleTrainConfig

    saved = MultiStyleTrainConfig(lambda_gram=0.0).to_dict()
    del saved["lambda_gram"]  # what a run's config held before the term existed
    assert MultiStyleTrainConfig.from_dict(saved).lambda_gram == 0.0
    assert MultiStyleTrainConfig().lambda_gram == 1.0  # the recipe's default today
    assert MultiStyleTrainConfig.from_dict(MultiStyleTrainConfig().to_dict()).lambda_gram == 1.0
