"""The skeleton-graph generator (models/graph.py, seed 003): its adjacency is the humanoid's,
one graph layer only reaches a bone's neighbours, its correction cannot jitter, and it
trains, saves and loads as a multi-style model (the properties it shares with the
temporal generator are checked on both in test_multistyle.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from stylecast.cli import main
from stylecast.models.graph import GraphConv, GraphStyleGenerator, skeleton_adjacency
from stylecast.models.multistyle import GENERATORS, MultiStyleConfig, make_generator
from stylecast.models.networks import bspline_basis
from stylecast.models.representation import get_representation
from stylecast.models.restyler import Restyler
from stylecast.models.styles import one_hot
from stylecast.models.train_multistyle import MultiStyleTrainer, train_multistyle
from stylecast.motion.humanoid import HUMANOID_BONES, HUMANOID_PARENTS
from tests.test_models import synthetic_words
from tests.test_multistyle import TINY_GRAPH, _generator, _tiny_cfg, _tiny_words, _x

pytestmark = pytest.mark.usefixtures("one_torch_thread")
J = len(HUMANOID_BONES)


def _bone(name: str) -> int:
    return HUMANOID_BONES.index(name)


def test_the_adjacency_is_the_humanoids_bone_graph():
    a = skeleton_adjacency()
    assert a.shape == (3, J, J)
    assert np.array_equal(a[0], np.eye(J))
    # A child hears exactly its parent, with weight 1; the root hears no parent.
    for child, parent in enumerate(HUMANOID_PARENTS):
        expected = np.zeros(J)
        if parent >= 0:
            expected[parent] = 1.0
        assert np.array_equal(a[1][:, child], expected)
    # A parent hears the mean of its children: the Hips three (Spine and both legs), a hand none.
    hips = a[2][:, _bone("Hips")]
    assert set(np.flatnonzero(hips)) == {_bone("Spine"), _bone("LeftUpperLeg"), _bone("RightUpperLeg")}
    assert np.allclose(hips[hips > 0], 1 / 3)
    assert not a[2][:, _bone("LeftHand")].any()


def test_one_graph_layer_reaches_only_a_bones_skeleton_neighbours():
    torch.manual_seed(0)
    conv = GraphConv(3, 5, skeleton_adjacency())
    x = torch.randn(2, J, 3, 10)
    moved = x.clone()
    moved[:, _bone("LeftLowerArm")] += 1.0
    changed = (conv(moved) - conv(x)).abs().amax(dim=(0, 2, 3)) > 1e-6
    assert {HUMANOID_BONES[j] for j in np.flatnonzero(changed.numpy())} == {
        "LeftUpperArm", "LeftLowerArm", "LeftHand"}
    # The learnt adjacency can add a link the skeleton lacks (the other hand).
    with torch.no_grad():
        conv.learnt[0, _bone("LeftLowerArm"), _bone("RightHand")] = 0.5
    changed = (conv(moved) - conv(x)).abs().amax(dim=(0, 2, 3)) > 1e-6
    assert changed[_bone("RightHand")]


def test_the_graph_generators_correction_lies_on_the_smooth_basis():
    """Whatever its weights, the correction (in the representation's pre-combine space) is
    a cubic B-spline over the word: no jitter by construction, as the temporal generator."""
    g, x = _generator(net=TINY_GRAPH), _x(2)
    rep = get_representation("euler")
    w = torch.from_numpy(np.tile(one_hot("elderly"), (2, 1))).float()
    captured = {}
    g.combine = lambda base, delta: captured.setdefault("delta", delta) + base  # record the correction
    g(x, w)
    delta = captured["delta"].detach().numpy()  # (B, F, T)
    basis = bspline_basis(TINY_GRAPH.frames, TINY_GRAPH.correction_knots)
    coef, *_ = np.linalg.lstsq(basis, delta.reshape(-1, delta.shape[-1]).T, rcond=None)
    residual = basis @ coef - delta.reshape(-1, delta.shape[-1]).T
    assert np.abs(delta).max() > 1e-3  # a real correction...
    assert np.abs(residual).max() < 1e-5  # ...entirely on the basis
    g.combine = rep.combine


def test_the_graph_generator_needs_channels_and_the_humanoid():
    rep = get_representation("euler")
    with pytest.raises(ValueError, match="graph_channels"):
        GraphStyleGenerator(MultiStyleConfig(), rep.combine)
    with pytest.raises(ValueError, match="22-bone humanoid"):
        GraphStyleGenerator(replace(TINY_GRAPH, joints=20), rep.combine)
    assert isinstance(make_generator(TINY_GRAPH, rep.combine), GraphStyleGenerator)
    assert set(GENERATORS) == {"temporal", "graph"}


def test_graph_training_is_deterministic_and_its_checkpoint_restyles_as_trained(tmp_path):
    words = _tiny_words()
    cfg = _tiny_cfg(network=TINY_GRAPH, ema=0.0)
    states = []
    for _ in range(2):
        t = MultiStyleTrainer(cfg, words, device="cpu")
        t.run_epoch()
        states.append({k: v.clone() for k, v in t.model.state_dict().items()})
    assert all(torch.equal(states[0][k], states[1][k]) for k in states[0])
    trainer = train_multistyle(_tiny_cfg(network=TINY_GRAPH, ema=0.0), tmp_path, words, device="cpu",
                               progress=False, log=lambda *_: None)
    r = Restyler.load(tmp_path / "model.safetensors")
    assert isinstance(r.model, GraphStyleGenerator) and r.model.joint_embedding.shape == (1, J, 4, 1)
    trained = {k[2:]: v for k, v in trainer.model.state_dict().items() if k.startswith("G.")}
    loaded = r.model.state_dict()
    assert trained.keys() == loaded.keys() and all(torch.equal(trained[k], loaded[k]) for k in trained)
    src = synthetic_words(2, 5)
    out = r.with_style("elderly").restyle_words(src)
    assert out.shape == src.shape and np.abs(out - src).max() > 1e-4  # one tiny epoch: it restyles a little
    assert np.abs(r.with_mix(one_hot("elderly"), intensity=0.0).restyle_words(src) - src).max() < 1e-5


def test_train_refuses_an_unknown_generator_and_graph_without_styles_all(tmp_path, capsys):
    assert main(["train", "--styles", "all", "--generator", "gcn", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "--generator 'gcn' is not known" in err and "graph" in err and "Traceback" not in err
    assert main(["train", "--generator", "graph", "--out", str(tmp_path)]) == 2
    assert "add --styles all" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())  # refused before anything was written
