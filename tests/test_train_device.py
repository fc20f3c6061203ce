"""`stylecast train --device` (issue 12): a tiny training on each device, deterministic
where torch can be, never a traceback where it cannot."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from stylecast.models.networks import NetworkConfig
from stylecast.models.train import TrainConfig, train

from .test_models import synthetic_words

TINY = NetworkConfig(g_hidden=16, g_blocks=1, d_hidden=8)


def tiny_run(tmp_path, device: str, seed: int = 3) -> tuple[dict, list[str]]:
    a, b = synthetic_words(8, 1), synthetic_words(8, 2)
    cfg = TrainConfig(epochs=2, batch_size=4, words_per_epoch=8, seed=seed, network=TINY, val_words=4)
    lines: list[str] = []
    trainer = train(cfg, tmp_path, a, b, a[:4], b[:4], device=device, progress=False, log=lines.append)
    weights = {k: v.detach().cpu().clone() for k, v in trainer.model.state_dict().items()}
    return weights, lines


def test_tiny_training_on_the_cpu_is_strictly_deterministic(tmp_path):
    w1, lines = tiny_run(tmp_path / "1", "cpu")
    assert torch.are_deterministic_algorithms_enabled()
    assert not torch.is_deterministic_algorithms_warn_only_enabled()  # a new op without one must fail loudly
    w2, _ = tiny_run(tmp_path / "2", "cpu")
    assert all(torch.equal(w1[k], w2[k]) for k in w1)
    assert not any(line.startswith("note:") for line in lines)
    assert any("on cpu" in line for line in lines)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device on this machine")
def test_tiny_training_on_cuda_runs_and_names_any_nondeterministic_op_in_one_line(tmp_path):
    w1, lines = tiny_run(tmp_path / "1", "cuda")
    assert any("on cuda" in line for line in lines)
    assert all(np.isfinite(v.numpy()).all() for v in w1.values())
    notes = [line for line in lines if line.startswith("note:")]
    assert len(notes) == len(set(notes))  # each op once, not once per step
    w2, _ = tiny_run(tmp_path / "2", "cuda")
    if not notes:  # every op deterministic on this device: the two runs agree exactly
        assert all(torch.equal(w1[k], w2[k]) for k in w1)


def test_train_cli_refuses_a_missing_cuda_device_before_loading_data(tmp_path, capsys):
    if torch.cuda.is_available():
        pytest.skip("this machine has CUDA")
    from stylecast.cli import main

    rc = main(["train", "--out", str(tmp_path), "--device", "cuda", "--data", str(tmp_path / "no-data")])
    assert rc != 0
    err = capsys.readouterr().err
    assert "no CUDA device" in err and "Traceback" not in err
