"""models/averaging.py and `train --ema`: the generators' weight average over training."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from stylecast.cli import main
from stylecast.models import checkpoint as ckpt
from stylecast.models.averaging import WeightAverage
from stylecast.models.train import train
from stylecast.models.train_multistyle import CODE_TABLE, train_multistyle
from tests.test_models import _tiny_cfg, synthetic_words
from tests.test_multistyle import _tiny_cfg as _tiny_multistyle_cfg
from tests.test_multistyle import _tiny_words

pytestmark = pytest.mark.usefixtures("one_torch_thread")
QUIET = dict(device="cpu", progress=False, log=lambda *_: None)


class _Two(torch.nn.Module):
    def __init__(self):
        super().__init__()
        self.G = torch.nn.Linear(1, 1, bias=False)
        self.D = torch.nn.Linear(1, 1, bias=False)
        self.G.register_buffer("count", torch.zeros((), dtype=torch.long))


def test_the_average_is_the_ramped_exponential_mean_of_the_named_weights_only():
    m = _Two()
    with torch.no_grad():
        m.G.weight.fill_(0.0)
        m.D.weight.fill_(5.0)
    avg = WeightAverage(m, ("G.",), decay=0.5)
    assert set(avg.tensors()) == {"G.weight", "G.count"}
    expected = 0.0
    for step, value in enumerate((4.0, 8.0, 2.0, 6.0)):
        with torch.no_grad():
            m.G.weight.fill_(value)
            m.G.count.fill_(step + 1)
        keep = min(0.5, (1 + step) / (10 + step))  # 0.1, 0.18.., 0.25, then 0.5 is never reached here
        expected = keep * expected + (1 - keep) * value
        avg.update(m)
        assert avg.tensors()["G.weight"].item() == pytest.approx(expected, rel=1e-6)
        assert avg.tensors()["G.count"].item() == step + 1  # integer buffers are copied, never averaged
    assert m.G.weight.item() == 6.0  # the model itself is untouched


def test_a_decay_outside_zero_to_one_is_refused():
    with pytest.raises(ValueError, match="between 0 and 1"):
        WeightAverage(_Two(), ("G.",), decay=1.0)


def test_averaging_leaves_training_alone_and_ships_the_average(tmp_path):
    """The same seed with and without --ema: identical last weights (model-raw = model of the run
    without), and the shipped file of the --ema run is a different, averaged set."""
    a, b = synthetic_words(8, 1), synthetic_words(8, 2)
    train(_tiny_cfg(epochs=3, ema=0), tmp_path / "plain", a, b, a[:4], b[:4], **QUIET)
    train(_tiny_cfg(epochs=3, ema=0.9), tmp_path / "ema", a, b, a[:4], b[:4], **QUIET)
    plain, _ = ckpt.read_checkpoint(tmp_path / "plain" / "model.safetensors")
    raw, raw_meta = ckpt.read_checkpoint(tmp_path / "ema" / "model-raw.safetensors")
    averaged, meta = ckpt.read_checkpoint(tmp_path / "ema" / "model.safetensors")
    assert set(plain) == set(raw) == set(averaged)
    assert all((plain[k] == raw[k]).all() for k in plain)
    assert any(not (raw[k] == averaged[k]).all() for k in raw)
    assert "moving average" in meta["weights"] and "last" in raw_meta["weights"]


def _pair(cfg_kw, out, resume=False):
    a, b = synthetic_words(8, 1), synthetic_words(8, 2)
    train(_tiny_cfg(**cfg_kw), out, a, b, resume=resume, **QUIET)


def _multistyle(cfg_kw, out, resume=False):
    train_multistyle(_tiny_multistyle_cfg(**cfg_kw), out, _tiny_words(), resume=resume, **QUIET)


@pytest.mark.parametrize("kind", [_pair, _multistyle], ids=["pair", "multistyle"])
def test_a_resumed_run_ends_where_a_straight_run_does_average_included(kind, tmp_path):
    kind(dict(epochs=3, ema=0.9), tmp_path / "straight")
    kind(dict(epochs=2, ema=0.9), tmp_path / "resumed")
    kind(dict(epochs=3, ema=0.9), tmp_path / "resumed", resume=True)
    for name in ("model", "model-raw"):
        straight, _ = ckpt.read_checkpoint(tmp_path / "straight" / f"{name}.safetensors")
        resumed, meta = ckpt.read_checkpoint(tmp_path / "resumed" / f"{name}.safetensors")
        assert set(straight) == set(resumed) and all((straight[k] == resumed[k]).all() for k in straight)
    assert meta["epochs_completed"] == 3
    rows = (tmp_path / "resumed" / "losses.csv").read_text().strip().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == ["1", "2", "3"]


@pytest.mark.parametrize("kind", [_pair, _multistyle], ids=["pair", "multistyle"])
def test_resume_refuses_changed_settings_or_an_empty_folder_in_one_sentence(kind, tmp_path):
    from stylecast.motion.errors import UserError

    with pytest.raises(UserError, match="nothing to resume in .*; drop --resume"):
        kind(dict(epochs=2), tmp_path / "empty", resume=True)
    kind(dict(epochs=1, ema=0.9), tmp_path / "run")
    with pytest.raises(UserError, match=r"different settings \(ema\); use the same options"):
        kind(dict(epochs=2, ema=0.5), tmp_path / "run", resume=True)


def test_the_multistyle_json_carries_the_code_table_of_the_weights_beside_it(tmp_path):
    train_multistyle(_tiny_multistyle_cfg(epochs=2, ema=0.8), tmp_path, _tiny_words(), **QUIET)
    for name in ("model", "model-raw"):
        tensors, _ = ckpt.read_checkpoint(tmp_path / f"{name}.safetensors")
        side = json.loads((tmp_path / f"{name}.json").read_text())
        assert np.allclose(side["style_codes"], tensors[CODE_TABLE], atol=1e-6)
    raw, _ = ckpt.read_checkpoint(tmp_path / "model-raw.safetensors")
    avg, _ = ckpt.read_checkpoint(tmp_path / "model.safetensors")
    assert not (raw[CODE_TABLE] == avg[CODE_TABLE]).all()


@pytest.mark.parametrize("decay", ["1", "-0.5", "1.5"])
def test_train_refuses_a_decay_out_of_range_in_one_sentence_before_loading_data(decay, tmp_path, capsys):
    assert main(["train", "--out", str(tmp_path / "run"), "--ema", decay, "--data", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err
    assert "--ema must be 0 (off) or a decay between 0 and 1" in err and "Traceback" not in err
    assert not (tmp_path / "run").exists()
