"""The multi-style model: G(x, s) with style codes through AdaIN, its training, its
checkpoint kind, style mixes and the --style option (tiny networks, synthetic words; the
CLI runs use a few words of the shared Bandai data and are skipped without it)."""

from __future__ import annotations

import copy
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from stylecast.cli import main
from stylecast.models import checkpoint as ckpt
from stylecast.models.gait_amplitude import amplitudes
from stylecast.models.multistyle import MultiStyleConfig, StyleDiscriminator, make_generator
from stylecast.models.networks import to_channels
from stylecast.models.representation import get_representation
from stylecast.models.restyler import Restyler
from stylecast.models.restyler_multistyle import MultiStyleRestyler, code_and_intensity
from stylecast.models.styles import STYLES, describe_mix, one_hot, parse_mix
from stylecast.models.train_multistyle import MultiStyleTrainConfig, MultiStyleTrainer, train_multistyle
from stylecast.motion import rotations as rot
from stylecast.motion.errors import UserError
from stylecast.motion.footlock import FEET, feet_for
from tests.test_models import synthetic_words

TINY = MultiStyleConfig(g_hidden=16, g_blocks=1, d_hidden=8, code_dim=4)
TINY_GRAPH = MultiStyleConfig(g_blocks=1, d_hidden=8, code_dim=4, graph_channels=4)  # models/graph.py
# The properties every multi-style generator must have, checked on both kinds.
each_generator = pytest.mark.parametrize("net", [TINY, TINY_GRAPH], ids=["temporal", "graph"])
SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bandai"
CLIP = SHARED / "dataset-2" / "data" / "dataset-2_walk_normal_001.bvh.gz"
needs_data = pytest.mark.skipif(not CLIP.exists(), reason=f"the shared Bandai data is not at {SHARED}")
S = len(STYLES)


pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _generator(seed: int = 0, trained_like: bool = True, net: MultiStyleConfig = TINY) -> torch.nn.Module:
    """A tiny generator; ``trained_like``: its zero-initialised parts given random values, so
    the style code changes the output (as after training)."""
    torch.manual_seed(seed)
    rep = get_representation("euler")
    g = make_generator(net, rep.combine)
    if trained_like:
        with torch.no_grad():
            for p in g.parameters():
                p.add_(torch.randn_like(p) * 0.05)
    return g.eval()


def _x(n: int = 3, seed: int = 0) -> torch.Tensor:
    rep = get_representation("euler")
    f = rep.encode(synthetic_words(n, seed)).astype(np.float32)  # (B, 60, J, 3)
    return torch.from_numpy(f).reshape(n, 60, -1).transpose(1, 2).contiguous()


def _tiny_words(n: int = 24) -> dict:
    return {s: synthetic_words(n, 10 + k, amplitude=0.2 + 0.05 * k) for k, s in enumerate(STYLES)}


def _tiny_cfg(**kw) -> MultiStyleTrainConfig:
    """A tiny recipe; without the dynamics term, which needs every word's action (its own
    tests, ``test_dynamics_term.py``, train with it)."""
    return MultiStyleTrainConfig(**{"epochs": 1, "words_per_epoch": 28, "batch_size": 7, "network": TINY,
                                    "lambda_gram": 0.0, **kw})


# --- the network ------------------------------------------------------------------------------

@each_generator
def test_shapes_of_generator_and_discriminator(net):
    g, x = _generator(net=net), _x(3)
    w = torch.from_numpy(np.stack([one_hot(s) for s in ("elderly", "youthful", "active")])).float()
    assert g(x, w).shape == x.shape
    d = StyleDiscriminator(TINY)
    out = d(x, torch.tensor([0, 3, 6]))
    assert out.shape == (3, 1, 15)
    # Each word is scored by the head of its own style: channel k of the shared trunk.
    v = torch.diff(x, dim=2, prepend=x[:, :, :1]) * TINY.d_velocity_scale
    heads = d.net(torch.cat([x, v], dim=1))
    assert torch.equal(out[:, 0], torch.stack([heads[0, 0], heads[1, 3], heads[2, 6]]))


@each_generator
def test_a_fresh_generator_is_the_identity_for_every_style_and_mix(net):
    g, x = _generator(trained_like=False, net=net), _x(4)
    for w in (one_hot("elderly"), parse_mix("active:0.3,feminine:0.7")):
        y = g(x, torch.from_numpy(np.tile(w, (4, 1))).float())
        assert torch.allclose(y, x, atol=1e-6)


@each_generator
def test_one_hot_mix_is_that_style_and_a_half_mix_lies_between(net):
    g, x = _generator(net=net), _x(2)
    e = torch.from_numpy(np.tile(one_hot("elderly"), (2, 1))).float()
    y = torch.from_numpy(np.tile(one_hot("youthful"), (2, 1))).float()
    via_mix = torch.from_numpy(np.tile(parse_mix("elderly:1,youthful:0"), (2, 1))).float()
    assert torch.equal(g(x, via_mix), g(x, e))
    assert not torch.allclose(g(x, e), g(x, y), atol=1e-4)  # the code matters
    # The mixed code is the mean of the two codes.
    half = torch.from_numpy(np.tile(parse_mix("elderly:0.5,youthful:0.5"), (2, 1))).float()
    table = g.codes.table
    assert torch.allclose(g.codes(half)[0], (table[1] + table[6]) / 2, atol=1e-6)


@each_generator
def test_intensity_scales_the_correction(net):
    g, x = _generator(net=net), _x(2)
    w = torch.from_numpy(np.tile(one_hot("elderly"), (2, 1))).float()
    assert torch.allclose(g(x, w, torch.zeros(2)), x, atol=1e-6)
    assert torch.allclose(g(x, w, torch.ones(2)), g(x, w), atol=1e-6)
    half = g(x, w, torch.full((2,), 0.5))
    assert not torch.allclose(half, x, atol=1e-4) and not torch.allclose(half, g(x, w), atol=1e-4)


@each_generator
def test_per_word_styles_in_one_batch_equal_separate_calls(net):
    g, x = _generator(net=net), _x(3)
    mixes = [one_hot("elderly"), one_hot("youthful"), parse_mix("active:0.5,normal:0.5")]
    together = g(x, torch.from_numpy(np.stack(mixes)).float())
    for i, w in enumerate(mixes):
        alone = g(x[i:i + 1], torch.from_numpy(w[None]).float())
        assert torch.allclose(together[i:i + 1], alone, atol=1e-5)


# --- the performer's own style -------------------------------------------------------------------

def _restyler(net: MultiStyleConfig = TINY) -> MultiStyleRestyler:
    return MultiStyleRestyler(_generator(net=net), get_representation("euler"), {"styles": list(STYLES)})


def _max_degrees(a: np.ndarray, b: np.ndarray) -> float:
    return float(rot.angle_between(a, b).max())


@each_generator
def test_the_performers_own_style_is_the_input_and_its_half_mix_is_half_the_restyle(net):
    """The generator is told only a target, and its code for the input's own style is not
    the identity (the known-bad case: the code path, which moves these words); the share of
    the performer's style is the input as performed instead."""
    r, words = _restyler(net), synthetic_words(3, 1)
    assert r.performer_style == "normal"
    assert _max_degrees(r.for_target("normal").restyle_words(words), words) < 1e-3
    code_path = r.with_mix(one_hot("normal"))
    code_path.performer_style = "elderly"  # the normal code run through the generator
    assert _max_degrees(code_path.restyle_words(words), words) > 0.05
    half = r.with_style("elderly:0.5,normal:0.5").restyle_words(words)
    assert np.allclose(half, r.with_mix(one_hot("elderly"), intensity=0.5).restyle_words(words), atol=1e-6)
    assert _max_degrees(half, words) > 0.05 and _max_degrees(half, r.for_target("elderly").restyle_words(words)) > 0.05
    # What the generator is given: a mix without the performer's style is its code at full
    # strength, as before; with it, the other styles' code at the share they have.
    mixes = np.stack([parse_mix("elderly:0.25,youthful:0.75"), parse_mix("elderly:0.5,normal:0.5"),
                      one_hot("normal")]).astype(np.float32)
    code, kept = code_and_intensity(mixes, np.broadcast_to(np.float32(one_hot("normal")), mixes.shape))
    assert np.array_equal(code[0], mixes[0]) and np.array_equal(code[1], np.float32(one_hot("elderly")))
    assert code.dtype == kept.dtype == np.float32 and kept.tolist() == [1.0, 0.5, 0.0]


def test_told_another_performer_style_that_style_passes_through_and_normal_is_restyled():
    r, words = _restyler().with_performer_style("elderly"), synthetic_words(3, 2)
    assert (r.source_style, _restyler().source_style) == ("elderly", "normal")  # what the status line names
    assert _max_degrees(r.for_target("elderly").restyle_words(words), words) < 1e-3
    assert _max_degrees(r.for_target("normal").restyle_words(words), words) > 0.05
    # Each word its own mix, one call: the same as each alone, the performer's share included.
    mixes = np.stack([one_hot("elderly"), one_hot("normal"), parse_mix("elderly:0.5,active:0.5")])
    together = r.restyle_words(words, mixes)
    for i, w in enumerate(mixes):
        assert np.allclose(together[i], r.with_mix(w).restyle_words(words[i:i + 1])[0], atol=1e-6)
    with pytest.raises(UserError, match="unknown performer style 'ancient'.*youthful, or auto"):
        r.with_performer_style("ancient")


@needs_data
def test_the_shipped_model_passes_a_normal_performance_told_normal_through():
    """On a real walk: the code path moved it by degrees (3.55 a bone on average over the
    held-out normal words); the performer's own style now leaves it as performed."""
    from stylecast.models import data as D

    words = D.cut_words(D.decode_file(CLIP)[0].astype(np.float64), 30)[:4]
    r = Restyler.load("multistyle")
    assert _max_degrees(r.restyle_words(words), words) < 1e-3  # its default style is normal
    assert _max_degrees(r.with_performer_style("elderly").restyle_words(words), words) > 5.0


@needs_data
def test_the_shipped_models_standing_feet_stay_where_they_landed():
    """A held-out standing take (a wave) restyled towards youthful through the stream, with
    the model's own lock (the stance): the planted feet move no more than the input's. The
    known-bad case beside it, the stance following the restyled legs at 0.01 cm and 0.04
    degrees a frame while planted (the previous setting): 2.3x the input's here."""
    from stylecast.models import data as D, metrics as M
    from stylecast.models.eval_measures import mean_ratio
    from stylecast.models.restyle import restyle_rotations
    from stylecast.motion.footlock import AUTO_FEET
    from stylecast.motion.words import DEFAULT_HOP, stream_settings_of

    files = D.list_files(D.default_data_dir())
    take = [f for f in D.files_for_style(files, "normal", "val") if f.action == "wave-both-hands"][0]
    m, skeleton = D.load_motions([take])[0], D.bandai_skeleton(files)
    q, roots = m.rotations.astype(np.float64), m.root_positions.astype(np.float64)
    r = Restyler.load("multistyle").for_target("youthful").with_performer_style("normal")
    p_in = M.world_positions(q, roots, skeleton)
    planted = M.planted(p_in)
    slides = {}
    for name, contacts in (("still", feet_for(AUTO_FEET, r)),
                           ("creeping", replace(feet_for(AUTO_FEET, r), stance_rate=0.01, turn_rate=0.04))):
        out, moved = restyle_rotations(q, r.restyle_words, DEFAULT_HOP, contacts=contacts, roots=roots,
                                       skeleton=skeleton, **stream_settings_of(r))
        p_out = M.world_positions(out, roots if moved is None else moved, skeleton)
        slides[name] = mean_ratio(M.slide_samples(p_out, planted), M.slide_samples(p_in, planted))
    assert feet_for(AUTO_FEET, r).stance_cap > 0  # the stance lock, the model's own towards youthful
    assert slides["still"] < 1.1
    assert slides["creeping"] > 1.5


# --- the style names ---------------------------------------------------------------------------

def test_style_mixes_parse_normalise_and_refuse_unknown_names():
    assert np.allclose(parse_mix("elderly"), one_hot("elderly"))
    w = parse_mix("elderly:1, youthful:3")
    assert w[STYLES.index("elderly")] == pytest.approx(0.25) and w.sum() == pytest.approx(1)
    assert describe_mix(w) == "youthful 0.75 + elderly 0.25"
    for bad, words in (("sleepy", "unknown style 'sleepy'"), ("elderly:x", "not a number"),
                       ("elderly:0", "positive weight"), ("elderly:-1", ">= 0")):
        with pytest.raises(UserError, match=words) as e:
            parse_mix(bad)
        assert "\n" not in str(e.value)
    with pytest.raises(UserError) as e:
        parse_mix("sleepy")
    assert all(s in str(e.value) for s in STYLES)


# --- training ------------------------------------------------------------------------------------

def _state(trainer) -> dict:
    return {k: v.clone() for k, v in trainer.model.state_dict().items()}


def test_training_is_deterministic_for_a_seed_and_moves_the_weights():
    words = _tiny_words()
    runs = []
    for seed in (3, 3, 4):
        t = MultiStyleTrainer(_tiny_cfg(seed=seed), words, device="cpu")
        before = _state(t)
        t.run_epoch()
        runs.append((before, _state(t)))
    (b0, a0), (_, a1), (_, a2) = runs
    assert all(torch.equal(a0[k], a1[k]) for k in a0)  # same seed, same weights
    assert any(not torch.equal(a0[k], a2[k]) for k in a0)  # another seed differs
    assert not torch.equal(a0["G.head.weight"], b0["G.head.weight"])  # the head left zero: it learnt


def test_the_mismatch_term_scores_real_words_of_other_styles_as_fake_on_the_target_head():
    """The discriminator's loss with ``lambda_mismatch`` is the plain one plus that weight
    times the LSGAN fake term of the REAL words on the head of the style they were sent to
    (a style not their own): read off one step from the same state, where the generator's
    update (which the term does not touch) is the same in both runs."""
    src = torch.arange(S).repeat(2)
    tgt = (src + 3) % S
    base = MultiStyleTrainer(_tiny_cfg(seed=5, lr=2e-3), _tiny_words(8), device="cpu")
    x = to_channels(torch.stack([base.words[s][i] for s, i in zip(src.tolist(), [0] * S + [1] * S)]))
    for _ in range(20):  # the heads learn apart, so the right and the wrong head score differently
        base.step(x, src, tgt)
    with torch.no_grad():
        wrong_head, own_head = base.model.D(x, tgt), base.model.D(x, src)
    losses = {}
    for weight in (0.0, 2.0):
        t = copy.deepcopy(base)
        t.cfg = replace(base.cfg, lambda_mismatch=weight)
        losses[weight] = t.step(x, src, tgt)["D"]
    expected = 2.0 * 0.5 * (wrong_head ** 2).mean().item()
    assert losses[2.0] - losses[0.0] == pytest.approx(expected, rel=1e-4)
    # Known-bad: the term taken on the words' own head (which scores them as real, near 1)
    # would add several times as much, far outside that tolerance.
    assert 2.0 * 0.5 * (own_head ** 2).mean().item() > 3 * expected


def test_every_style_and_every_target_is_drawn_and_no_word_targets_its_own_style():
    t = MultiStyleTrainer(_tiny_cfg(), _tiny_words(), device="cpu")
    plan = t.epoch_plan(np.random.default_rng(0))
    src = np.concatenate([p[0] for p in plan])
    tgt = np.concatenate([p[2] for p in plan])
    assert np.all(np.bincount(src, minlength=S) == 4)  # 28 words: an equal share of 4 per style
    assert np.all(src != tgt)
    big = MultiStyleTrainer(_tiny_cfg(words_per_epoch=700), _tiny_words(), device="cpu")
    tgt = np.concatenate([p[2] for p in big.epoch_plan(np.random.default_rng(1))])
    assert set(tgt) == set(range(S))


def test_a_trained_checkpoint_loads_as_the_multistyle_kind(tmp_path):
    train_multistyle(_tiny_cfg(), tmp_path, _tiny_words(), _tiny_words(8), device="cpu", progress=False,
                     log=lambda *_: None)
    r = Restyler.load(tmp_path / "model.safetensors")
    assert isinstance(r, MultiStyleRestyler)
    meta = json.loads((tmp_path / "model.json").read_text())
    assert meta["kind"] == "multistyle" and meta["styles"] == list(STYLES)
    assert np.allclose(np.array(meta["style_codes"]), r.style_codes(), atol=1e-6)
    words = synthetic_words(3, 7)
    e = r.with_style("elderly")
    assert np.allclose(e.restyle_words(words), r.for_target("elderly").restyle_words(words))
    per_row = r.restyle_words(words, np.stack([one_hot("elderly"), one_hot("youthful"), one_hot("elderly")]))
    assert np.allclose(per_row[0], e.restyle_words(words[:1])[0], atol=1e-6)
    assert np.allclose(per_row[1], r.with_style("youthful").restyle_words(words[1:2])[0], atol=1e-6)
    assert r.with_style("elderly:0.5,youthful:0.5").target_style == "elderly 0.50 + youthful 0.50"
    with pytest.raises(UserError, match="no directions"):
        r.with_direction("b2a")
    # --feet auto: the stance, but on the input's ankles and path for a mix led by elderly or exhausted
    assert r.feet == "stance" and r.with_style("youthful").feet == "stance"
    assert r.with_style("elderly").feet == "path" and r.with_style("exhausted:0.6,feminine:0.4").feet == "path"
    assert r.with_style("exhausted:0.4,feminine:0.6").feet == "stance"
    elderly = r.with_style("elderly")
    assert feet_for("auto", elderly, "input") == replace(FEET["path"], **elderly.amplitudes())
    assert elderly.amplitudes() == amplitudes("normal", {"elderly": 1.0})  # the arms swing, the hips bob as elderly
    # ...and the hips a style asks for (quick_hips_of_style): masculine's follow within 2
    # frames, youthful's within the stance's 8, a mix's by its weights
    assert feet_for("auto", r.with_style("masculine")).pelvis_quick_share == 1.0
    youthful = r.with_style("youthful")
    assert feet_for("auto", youthful) == replace(FEET["stance"], pace=youthful.pace(), **youthful.amplitudes())
    assert r.with_style("masculine:0.5,youthful:0.5").quick_hips() == pytest.approx(0.5)


def test_a_multistyle_checkpoint_with_foreign_styles_or_kind_is_refused(tmp_path):
    train_multistyle(_tiny_cfg(), tmp_path, _tiny_words(), device="cpu", progress=False, log=lambda *_: None)
    tensors, meta = ckpt.read_checkpoint(tmp_path / "model.safetensors")
    for change, words in (({"styles": ["normal", "sleepy"]}, "names the styles"), ({"kind": "diffusion"}, "kind")):
        bad = ckpt.save_checkpoint(tmp_path / "bad.safetensors", tensors, {**meta, **change})
        with pytest.raises(UserError, match=words) as e:
            Restyler.load(bad)
        assert "\n" not in str(e.value)


def test_a_pair_model_takes_one_of_its_styles_and_refuses_others():
    pair = Restyler.load("normal2exhausted")
    assert pair.with_style("exhausted").direction == "a2b"
    assert pair.with_style("normal").direction == "b2a"
    with pytest.raises(UserError, match="only, not towards 'elderly'"):
        pair.with_style("elderly")
    with pytest.raises(UserError, match="cannot mix"):
        pair.with_style("normal:0.5,exhausted:0.5")


# --- the commands ------------------------------------------------------------------------------

@needs_data
def test_train_styles_all_and_restyle_with_a_style_and_a_mix(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["train", "--styles", "all", "--max-words", "8", "--epochs", "1", "--words-per-epoch", "14",
                 "--batch-size", "7", "--threads", "1", "--out", str(run), "--no-progress"]) == 0
    assert len((run / "losses.csv").read_text().strip().splitlines()) == 2
    model = str(run / "model.safetensors")
    for style, shown in (("elderly", "normal -> elderly"),
                         ("elderly:0.5,youthful:0.5", "elderly 0.50 + youthful 0.50")):
        out = tmp_path / "out.bvh"
        assert main(["restyle", str(CLIP), "-o", str(out), "--model", model, "--style", style, "--threads", "1"]) == 0
        assert shown in capsys.readouterr().out and out.exists()


def test_restyle_refuses_an_unknown_style_before_reading_anything(tmp_path, capsys):
    # Neither the clip nor the model exists: the style is checked first.
    code = main(["restyle", str(tmp_path / "absent.bvh"), "-o", str(tmp_path / "o.bvh"), "--model",
                 str(tmp_path / "absent.safetensors"), "--style", "sleepy"])
    err = capsys.readouterr().err
    assert code == 2 and "unknown style 'sleepy'" in err and "youthful" in err and "Traceback" not in err


def test_restyle_checks_the_performer_style_first_and_a_pair_model_refuses_another_source(tmp_path, capsys):
    code = main(["restyle", str(tmp_path / "absent.bvh"), "-o", str(tmp_path / "o.bvh"), "--model",
                 str(tmp_path / "absent.safetensors"), "--performer-style", "sleepy"])
    err = capsys.readouterr().err
    assert code == 2 and "unknown performer style 'sleepy'" in err and "Traceback" not in err
    # The shipped pair model restyles normal input: told elderly, one sentence before the clip is read.
    code = main(["restyle", str(tmp_path / "absent.bvh"), "-o", str(tmp_path / "o.bvh"), "--performer-style",
                 "elderly"])
    err = capsys.readouterr().err
    assert code == 2 and "restyles normal input in this direction, not elderly" in err and "Traceback" not in err
    # ...and cannot read the performer's style at all.
    code = main(["restyle", str(tmp_path / "absent.bvh"), "-o", str(tmp_path / "o.bvh"), "--performer-style", "auto"])
    err = capsys.readouterr().err
    assert code == 2 and "cannot read the performer's style" in err and "Traceback" not in err


def test_eval_refuses_an_unknown_target_and_needs_one_for_a_multistyle_model(tmp_path, capsys):
    assert main(["eval", "--model", str(tmp_path / "absent.safetensors"), "--target", "sleepy",
                 "--out", str(tmp_path / "e")]) == 2
    err = capsys.readouterr().err
    assert "unknown style 'sleepy'" in err and "elderly" in err and "Traceback" not in err
    train_multistyle(_tiny_cfg(), tmp_path / "m", _tiny_words(), device="cpu", progress=False, log=lambda *_: None)
    assert main(["eval", "--model", str(tmp_path / "m" / "model.safetensors"), "--out", str(tmp_path / "e")]) == 2
    err = capsys.readouterr().err
    assert "--target" in err and "youthful" in err and "Traceback" not in err
    # A direction it would ignore: refused, before the minutes of the judges' training.
    assert main(["eval", "--model", str(tmp_path / "m" / "model.safetensors"), "--target", "elderly", "--direction",
                 "b2a", "--out", str(tmp_path / "e")]) == 2
    assert "has no directions" in capsys.readouterr().err
    assert main(["eval", "--model", "normal2exhausted", "--target", "elderly", "--out", str(tmp_path / "e")]) == 2
    assert "not towards 'elderly'" in capsys.readouterr().err
    assert main(["eval", "--model", "normal2exhausted", "--source", "elderly", "--out", str(tmp_path / "e")]) == 2
    assert "not from elderly" in capsys.readouterr().err
    assert main(["eval", "--model", "normal2exhausted", "--source", "sleepy", "--out", str(tmp_path / "e")]) == 2
    assert "unknown style 'sleepy'" in capsys.readouterr().err


def test_pca_projection_keeps_the_main_axis():
    from stylecast.models.eval_plots import pca_2d

    rng = np.random.default_rng(0)
    x = np.c_[rng.normal(size=200) * 10, rng.normal(size=200), rng.normal(size=200) * 0.1]
    xy, var = pca_2d(x)
    assert xy.shape == (200, 2) and var[0] > 0.95 and var[0] > var[1]
    assert abs(np.corrcoef(xy[:, 0], x[:, 0])[0, 1]) > 0.99
