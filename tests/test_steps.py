"""The step term (``models/steps.py``): a restyle's feet may step no higher than its target
style's do, measured against the evaluation's numpy step height on known motion."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from stylecast.cli import main
from stylecast.models import data as D
from stylecast.models.content import ActionLabels
from stylecast.models.metrics import step_heights, world_positions
from stylecast.models.networks import to_channels
from stylecast.models.representation import get_representation
from stylecast.models.restyler import Restyler
from stylecast.models.steps import SLACK, StepTerm
from stylecast.models.styles import STYLES
from stylecast.models.train_multistyle import MultiStyleTrainer
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default

from .test_multistyle import _tiny_cfg, _tiny_words

pytestmark = pytest.mark.usefixtures("one_torch_thread")

J = len(HUMANOID_BONES)
THIGHS = (HUMANOID_BONES.index("LeftUpperLeg"), HUMANOID_BONES.index("RightUpperLeg"))
KNEES = (HUMANOID_BONES.index("LeftLowerLeg"), HUMANOID_BONES.index("RightLowerLeg"))
REP = get_representation("euler")


def stepping_words(knee_deg: float, n: int = 1) -> np.ndarray:
    """Words (n, 60, J, 4): a fixed pose, each knee bending from 0 to ``knee_deg`` and back
    twice a word, the legs in turn: a step on the spot whose height grows with the bend."""
    rng = np.random.default_rng(5)
    rotvec = np.repeat(rng.normal(scale=0.05, size=(n, 1, J, 3)), 60, axis=1)
    phase = 2 * np.pi * 2 * np.arange(60) / 60
    for side, knee in enumerate(KNEES):
        rotvec[:, :, knee, 0] += np.radians(knee_deg) * np.maximum(np.sin(phase + np.pi * side), 0.0)
    return Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_quat().reshape(n, 60, J, 4)


def channels(words: np.ndarray) -> torch.Tensor:
    return to_channels(torch.from_numpy(REP.encode(words)))


def numpy_heights(words: np.ndarray) -> np.ndarray:
    """(n, 2) the evaluation's step height of each word, from the metrics' numpy forward
    kinematics with the hips at the origin."""
    skeleton = humanoid_skeleton_default()
    return np.stack([step_heights(world_positions(w, np.zeros((60, 3)), skeleton)) for w in words])


def two_style_term(words_a: np.ndarray, words_b: np.ndarray, actions_a, actions_b, classes: int) -> StepTerm:
    """A term whose first two styles learn their caps from these words (the rest copy the first)."""
    words = [channels(words_a), channels(words_b)] + [channels(words_a)] * (len(STYLES) - 2)
    actions = [torch.as_tensor(actions_a), torch.as_tensor(actions_b)] + [torch.as_tensor(actions_a)] * (len(STYLES) - 2)
    return StepTerm(REP, humanoid_skeleton_default(), "cpu", words, actions, classes)


def test_the_step_height_is_the_evaluations_on_the_same_motion():
    words = np.concatenate([stepping_words(knee) for knee in (0.0, 20.0, 60.0)])
    term = two_style_term(words, words, [0, 0, 0], [0, 0, 0], 1)
    got = term.heights(channels(words)).numpy()
    expected = numpy_heights(words)
    assert expected[0].max() < 0.05 and expected[2].min() > 5.0  # still feet, and a real step
    np.testing.assert_allclose(got, expected, atol=1e-3)


def test_caps_are_learned_per_action_from_each_styles_words():
    """Style b steps as high as a in action 0 and higher in action 1; the caps say so."""
    low, high = stepping_words(30.0, 2), stepping_words(60.0, 2)
    term = two_style_term(np.concatenate([low, low]), np.concatenate([low, high]), [0, 0, 1, 1], [0, 0, 1, 1], 2)
    h_low, h_high = numpy_heights(low).mean(), numpy_heights(high).mean()
    assert term.ratio[0, 0, 1].item() == pytest.approx(1.0, abs=1e-6)
    assert term.ratio[1, 0, 1].item() == pytest.approx(h_high / h_low, rel=1e-3)
    assert term.ratio[1, 1, 0].item() == pytest.approx(h_low / h_high, rel=1e-3)


def test_restyles_at_or_below_the_cap_pay_nothing():
    low, high = stepping_words(30.0), stepping_words(60.0)
    term = two_style_term(high, low, [0], [0], 1)  # style 1 steps lower than style 0
    a, s0, s1 = torch.zeros(1, dtype=torch.long), torch.zeros(1, dtype=torch.long), torch.ones(1, dtype=torch.long)
    assert term(channels(high), channels(high), a, s0, s0).item() == 0.0  # towards its own style: cap 1x + slack
    assert term(channels(low), channels(high), a, s0, s1).item() == pytest.approx(0.0, abs=1e-4)  # as high as allowed
    assert term(channels(stepping_words(20.0)), channels(high), a, s0, s1).item() == 0.0  # lower is free


def test_a_restyle_that_lifts_the_feet_above_the_target_styles_pays_the_excess_in_cm():
    """The known-bad case: a high-stepping restyle towards a style that steps lower pays what
    it steps above the learned cap, by the evaluation's own numpy figures."""
    low, high = stepping_words(30.0), stepping_words(60.0)
    term = two_style_term(high, low, [0], [0], 1)
    a, s0, s1 = torch.zeros(1, dtype=torch.long), torch.zeros(1, dtype=torch.long), torch.ones(1, dtype=torch.long)
    h_low, h_high = numpy_heights(low)[0], numpy_heights(high)[0]  # each foot's, cm
    cap = h_low.mean() / h_high.mean() * h_high + SLACK  # the styles' ratio is over both feet
    expected = np.maximum(h_high - cap, 0).mean()
    assert expected > 3.0
    assert term(channels(high), channels(high), a, s0, s1).item() == pytest.approx(expected, rel=1e-3)


def test_an_action_missing_from_a_style_has_no_cap():
    low, high = stepping_words(30.0), stepping_words(60.0)
    term = two_style_term(np.concatenate([high, high]), low, [0, 1], [0], 2)  # style 1 has no action 1
    assert torch.isinf(term.ratio[1, 0, 1]) and torch.isinf(term.ratio[1, 1, 0])
    a, s0, s1 = torch.ones(1, dtype=torch.long), torch.zeros(1, dtype=torch.long), torch.ones(1, dtype=torch.long)
    assert term(channels(high), channels(high), a, s0, s1).item() == 0.0
    assert term(channels(high), channels(high), a * 0, s0, s1).item() > 3.0


def test_its_gradient_lowers_a_step_that_is_too_high():
    low, high = stepping_words(30.0), stepping_words(60.0)
    term = two_style_term(high, low, [0], [0], 1)
    a, s0, s1 = torch.zeros(1, dtype=torch.long), torch.zeros(1, dtype=torch.long), torch.ones(1, dtype=torch.long)
    x = channels(high).requires_grad_(True)
    before = term.heights(x).mean().item()
    loss = term(x, channels(high), a, s0, s1)
    loss.backward()
    with torch.no_grad():
        lowered = x - 1e-3 * x.grad / x.grad.abs().max()
    assert term.heights(lowered).mean().item() < before


def _actions(words: dict) -> ActionLabels:
    labels = {s: np.arange(len(w)) % 2 for s, w in words.items()}
    return ActionLabels(["raise", "wave"], labels, {s: v[:4] for s, v in labels.items()})


def test_the_multistyle_trainer_pays_it_when_asked_and_refuses_it_without_what_it_needs():
    words = _tiny_words()
    skeleton = humanoid_skeleton_default()
    off = MultiStyleTrainer(_tiny_cfg(), words, device="cpu")
    on = MultiStyleTrainer(_tiny_cfg(lambda_step=1.0), words, device="cpu", actions=_actions(words), skeleton=skeleton)
    start_off, start_on = off.model.state_dict(), on.model.state_dict()
    assert all(torch.equal(start_off[k], start_on[k]) for k in start_off)  # the same GAN at the start
    row_off, row_on = off.run_epoch(), on.run_epoch()
    assert row_off["step"] == 0.0 and row_on["step"] > 0.0
    with pytest.raises(UserError, match="--lambda-step needs the actors' skeleton") as e:
        MultiStyleTrainer(_tiny_cfg(lambda_step=1.0), words, device="cpu", actions=_actions(words))
    assert "\n" not in str(e.value)
    with pytest.raises(UserError, match="--lambda-step needs the action of every training word"):
        MultiStyleTrainer(_tiny_cfg(lambda_step=1.0), words, device="cpu", skeleton=skeleton)


@pytest.mark.parametrize("args, message", [
    (["--lambda-step", "1"], "--lambda-step is for --styles all"),
    (["--lambda-step", "-1", "--styles", "all"], "--lambda-step must be 0 or more"),
])
def test_bad_step_options_are_refused_before_any_data_is_read(tmp_path, capsys, args, message):
    code = main(["train", "--out", str(tmp_path / "run"), "--data", str(tmp_path / "nowhere"), *args])
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1


def test_tune_steps_lowers_the_steps_and_keeps_the_reader(bandai_root, tmp_path):
    """``stylecast tune-steps``, a short run (2 passes over 64 words of each style), on the
    shipped file with its generator replaced by an untrained one (the identity: its restyles
    step exactly as the input does, above the elderly cap, the known-bad case): held-out
    normal walks sent to elderly step lower after it, and the reader's tensors and every
    other entry are kept."""
    from stylecast.models import checkpoint as ckpt
    from stylecast.models.multistyle import MultiStyleConfig, make_generator
    from stylecast.models.restyler import network_config, read_model
    from stylecast.models.steps import tune_steps

    data = bandai_root / "dataset-2" / "data"
    path = ckpt.resolve("multistyle")
    tensors, meta, rep = read_model(path)
    torch.manual_seed(0)
    untrained = make_generator(network_config(path, meta, MultiStyleConfig), rep.combine).state_dict()
    source = ckpt.save_checkpoint(tmp_path / "untrained.safetensors",
                                  {**tensors, **{"G." + k: v for k, v in untrained.items()}}, meta)
    out = tune_steps(source, tmp_path / "tuned.safetensors", epochs=2, max_words=64, data_dir=data,
                     log=lambda *_: None)
    before, after = Restyler.load(source), Restyler.load(out)
    words = D.load_wordset("normal", "val", data, hop=30)
    walks = np.array([words.files[i].action == "walk" for i in words.file_index])
    x = to_channels(torch.from_numpy(words.features(before.rep)[walks]))
    elderly = torch.eye(len(STYLES))[[STYLES.index("elderly")] * len(x)]
    zeros = np.zeros(walks.sum(), int)
    term = two_style_term(words.words[walks], words.words[walks], zeros, zeros, 1)
    with torch.no_grad():
        y0, y1 = before.model(x, elderly), after.model(x, elderly)
    assert torch.allclose(y0, x, atol=1e-6)  # untrained: the identity
    assert term.heights(y1).mean() < 0.95 * term.heights(x).mean()
    tuned_tensors, tuned_meta, _ = read_model(out)
    assert all(np.array_equal(tuned_tensors[k], v) for k, v in tensors.items() if not k.startswith("G."))
    assert tuned_meta["reader"] == meta["reader"] and tuned_meta["step_tuning"]["lambda_step"] == 1.0


def test_tune_steps_refuses_a_pair_model_and_a_bad_out_in_one_sentence(capsys, tmp_path):
    assert main(["tune-steps", "--model", "normal2exhausted", "--out", str(tmp_path / "t.safetensors")]) == 2
    err = capsys.readouterr().err
    assert "is not a multi-style model; tune-steps tunes one" in err and err.count("\n") == 1
    assert main(["tune-steps", "--out", str(tmp_path / "t.bvh")]) == 2
    err = capsys.readouterr().err
    assert "must name a .safetensors file" in err and err.count("\n") == 1
    assert main(["tune-steps", "--lambda-step", "-1", "--out", str(tmp_path / "t.safetensors")]) == 2
    assert "--lambda-step must be 0 or more" in capsys.readouterr().err
