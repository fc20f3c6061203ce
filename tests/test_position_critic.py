"""The position critics (``models/position_critic.py``, ``train --lambda-position-adv``):
discriminators over the joints' world positions beside the paper's over rotations."""

from __future__ import annotations

import pytest
import torch

from stylecast.cli import main
from stylecast.models.content import PositionView
from stylecast.models.networks import to_channels
from stylecast.models.train import Trainer, train
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import humanoid_skeleton_default

from .test_models import _tiny_cfg, synthetic_words

pytestmark = pytest.mark.usefixtures("one_torch_thread")

SKELETON = humanoid_skeleton_default()


def _trainer(a, b, weight: float) -> Trainer:
    return Trainer(_tiny_cfg(lambda_position_adv=weight), a, b, a[:4], b[:4], device="cpu", skeleton=SKELETON)


def test_the_critics_leave_the_gan_stream_alone_train_and_reach_the_generators():
    a, b = synthetic_words(8, 1), synthetic_words(8, 2)
    off, on = _trainer(a, b, 0.0), _trainer(a, b, 1.0)
    assert off.critics is None
    start_off, start_on = off.model.state_dict(), on.model.state_dict()
    # Building the critics drew nothing from the GAN's random stream.
    assert all(torch.equal(start_off[k], start_on[k]) for k in start_off)
    critics_before = {k: v.clone() for k, v in on.critics.state_dict().items()}
    row_off, row_on = off.run_epoch(), on.run_epoch()
    assert row_off["position_a2b"] == row_off["D_positions"] == 0.0
    assert row_on["position_a2b"] > 0.0 and row_on["position_b2a"] > 0.0 and row_on["D_positions"] > 0.0
    after_off, after_on = off.model.state_dict(), on.model.state_dict()
    assert any(not torch.equal(after_off[k], after_on[k]) for k in after_off if k.startswith("G_"))
    assert any(not torch.equal(critics_before[k], v) for k, v in on.critics.state_dict().items())


def test_the_critics_see_the_real_words_positions_by_forward_kinematics():
    a, b = synthetic_words(8, 1), synthetic_words(8, 2)
    trainer = _trainer(a, b, 1.0)
    view = PositionView(trainer.rep, SKELETON, "cpu")
    expected = view(to_channels(torch.from_numpy(trainer._encode(b))))
    assert trainer.positions[1].shape == (8, 3 * len(SKELETON.parents), 60)
    assert torch.allclose(trainer.positions[1], expected, atol=1e-6)
    # Positions, not rotations: a hand sits tens of centimetres from the hips.
    assert trainer.positions[1].abs().max() > 0.2


def test_a_resumed_run_with_critics_continues_as_if_never_stopped(tmp_path):
    a, b = synthetic_words(8, 1), synthetic_words(8, 2)
    quiet = dict(device="cpu", progress=False, log=lambda *_: None, skeleton=SKELETON)
    whole = train(_tiny_cfg(epochs=2, lambda_position_adv=1.0), tmp_path / "whole", a, b, a[:4], b[:4], **quiet)
    train(_tiny_cfg(epochs=1, lambda_position_adv=1.0), tmp_path / "split", a, b, a[:4], b[:4], **quiet)
    resumed = train(_tiny_cfg(epochs=2, lambda_position_adv=1.0), tmp_path / "split", a, b, a[:4], b[:4],
                    resume=True, **quiet)
    for name, trainer_state in (("generators", lambda t: t.model.state_dict()),
                                ("critics", lambda t: t.critics.state_dict())):
        w, r = trainer_state(whole), trainer_state(resumed)
        assert all(torch.equal(w[k], r[k]) for k in w), name


def test_the_critics_need_the_skeleton_and_a_pair_model_in_one_sentence(capsys, tmp_path):
    a, b = synthetic_words(8, 1), synthetic_words(8, 2)
    with pytest.raises(UserError, match="--lambda-position-adv needs the actors' skeleton"):
        Trainer(_tiny_cfg(lambda_position_adv=1.0), a, b, device="cpu")
    assert main(["train", "--styles", "all", "--lambda-position-adv", "1", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "--lambda-position-adv is for a pair model" in err and err.count("\n") == 1
    assert main(["train", "--lambda-position-adv", "-1", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "--lambda-position-adv must be 0 or more" in err and err.count("\n") == 1
