"""``--performer-style auto``: the multi-style model reads the performer's style from each
word (``models/style_reader.py``) and passes the mix's overlap with it through as performed.

Plumbing on the tiny multi-style model with a reader made to read one style (a known
answer); reading itself on the shipped model's reader and held-out Bandai clips."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from stylecast.daemon.config import DaemonConfig
from stylecast.daemon.restylers import IdentityRestyler
from stylecast.models import checkpoint as ckpt
from stylecast.models import data as D
from stylecast.models import style_reader
from stylecast.models.classifier import WordClassifier, flush_subnormals
from stylecast.models.restyle import restyle_rotations
from stylecast.models.restyler import Restyler
from stylecast.models.restyler_multistyle import code_and_intensity
from stylecast.models.styles import READ, STYLES, one_hot
from stylecast.motion import rotations as rot
from stylecast.motion.errors import UserError
from stylecast.motion.footlock import NO_AMPLITUDES
from stylecast.motion.words import DEFAULT_HOP

from .test_daemon import offline, run_daemon, walk_clip
from . import test_daemon_styles
from .test_daemon_styles import _largest_difference, _served

tiny_multistyle = test_daemon_styles.tiny_multistyle  # that module's fixture, for this one


def _reader_tensors(features: int, reads: str | None = None) -> tuple[dict, dict]:
    """An untrained reader's tensors and metadata; with ``reads``, its head biased so that
    it reads every word as that style (probability above 0.999)."""
    net = WordClassifier(list(STYLES), features, seed=0, design=style_reader.DESIGN).net
    if reads is not None:
        with torch.no_grad():
            net[-1].weight.zero_()
            net[-1].bias.copy_(torch.tensor(20.0 * one_hot(reads) - 10.0))
    tensors = {style_reader.PREFIX + k: v.detach().numpy() for k, v in net.state_dict().items()}
    return tensors, {"styles": list(STYLES), "design": style_reader.DESIGN}


def _with_reader(path, out, reads: str | None = None):
    tensors, meta = ckpt.read_checkpoint(path)
    extra, info = _reader_tensors(Restyler.load(path).rep.channels * len(meta["bones"]), reads)
    return ckpt.save_checkpoint(out, {**tensors, **extra}, {**meta, "reader": info})


@pytest.fixture(scope="module")
def reads_elderly(tiny_multistyle, tmp_path_factory):
    """The tiny multi-style model with a reader that reads every word as elderly."""
    return _with_reader(tiny_multistyle, tmp_path_factory.mktemp("reader") / "reads-elderly.safetensors", "elderly")


def test_the_overlap_of_mix_and_reading_is_passed_through():
    """A reading enters as probabilities: the mix's overlap with it is the input as performed
    (a named style is a one-hot reading: ``tests/test_multistyle.py`` checks that case)."""
    reading = np.float32(0.6 * one_hot("elderly") + 0.4 * one_hot("normal"))[None].repeat(4, 0)
    mixes = np.stack([one_hot("elderly"), one_hot("youthful"), 0.5 * one_hot("elderly") + 0.5 * one_hot("youthful"),
                      0.5 * one_hot("elderly") + 0.5 * one_hot("normal")])
    code, kept = code_and_intensity(mixes.astype(np.float32), reading)
    np.testing.assert_allclose(kept, [0.4, 1.0, 0.5, 0.1], atol=1e-6)  # 60 % of elderly is as performed
    for row, style in zip(code, ("elderly", "youthful", "youthful", "normal")):  # normal: 0.1 not performed
        np.testing.assert_allclose(row, one_hot(style), atol=1e-6)


def test_a_reading_of_elderly_serves_what_naming_elderly_serves(reads_elderly):
    """``serve --performer-style auto`` with a reader that reads elderly sends exactly what
    ``--performer-style elderly`` sends: the input for an elderly target, the youthful
    restyle for a youthful one; and not what the default (normal) performer gets. The
    pace and the gait amplitude (``footlock.GaitAmplitude``) are measured from a named
    style's takes, so a style read word by word leaves both to the performer
    (``MultiStyleRestyler.pace``, ``amplitudes``): the named performer is served without
    them here (towards this mix the pace would be faster than the performer's, and a pace
    only slows, so only the amplitudes need taking off), and with them it differs."""
    model = Restyler.load(reads_elderly)
    as_performed = _served(IdentityRestyler())
    assert _largest_difference(_served(model, style="elderly", performer_style=READ), as_performed) < 1e-5
    assert _largest_difference(_served(model, style="elderly"), as_performed) > 1e-2  # the known-bad case
    assert model.with_performer_style(READ).amplitudes() == NO_AMPLITUDES
    own_amplitudes = Restyler.load(reads_elderly)
    own_amplitudes.amplitudes = lambda weights=None: dict(NO_AMPLITUDES)  # kept by its copies
    named = _served(own_amplitudes, style="elderly:0.5,youthful:0.5", performer_style="elderly")
    read = _served(model, style="elderly:0.5,youthful:0.5", performer_style=READ)
    assert _largest_difference(read, named) < 1e-5
    assert _largest_difference(_served(model, style="elderly:0.5,youthful:0.5"), named) > 1e-2
    assert _largest_difference(_served(model, style="elderly:0.5,youthful:0.5", performer_style="elderly"), read) > 1e-2


def test_restyle_live_equals_serve_when_the_style_is_read(reads_elderly, tiny_multistyle):
    """The reading is part of the model's one batched call, so ``restyle --live`` reads the
    same words ``serve`` does and sends the same frames. An untrained reader (probabilities
    that differ from word to word) is the stricter case."""
    untrained = _with_reader(tiny_multistyle, reads_elderly.parent / "untrained.safetensors")
    model = Restyler.load(untrained).with_style("elderly:0.5,youthful:0.5")
    reading = model.with_performer_style(READ)
    words = np.stack([walk_clip(60, seed=k).rotations for k in range(4)])
    p = reading.reader.read(torch.from_numpy(words))
    assert p.shape == (4, len(STYLES)) and np.ptp(p[:, STYLES.index("elderly")]) > 1e-4  # it varies by word
    _, frames = run_daemon(walk_clip(240), reading, hop=15, performers=1)
    live = np.stack([f.rotations for f in frames["p0"]])
    expected = offline(walk_clip(240), reading, 15)
    assert rot.angle_between(live, expected.rotations).max() < 1e-4  # degrees
    assert rot.angle_between(expected.rotations, offline(walk_clip(240), model, 15).rotations).max() > 1e-3


def test_a_words_reading_does_not_depend_on_its_batch(reads_elderly, tiny_multistyle):
    reader = Restyler.load(_with_reader(tiny_multistyle, reads_elderly.parent / "batch.safetensors")).reader
    words = torch.from_numpy(np.stack([walk_clip(60, seed=k).rotations for k in range(9)]))
    together = reader.read(words)
    alone = np.concatenate([reader.read(words[k:k + 1]) for k in range(len(words))])
    assert np.array_equal(together, alone)


def test_reading_is_refused_in_one_sentence_where_it_cannot_run(tiny_multistyle):
    DaemonConfig(performer_style=READ).validate()  # a known choice
    with pytest.raises(UserError, match="cannot read the performer's style.*--model multistyle"):
        Restyler.load("normal2exhausted").with_performer_style(READ)
    with pytest.raises(UserError, match="has no style reader.*stylecast train-reader"):
        Restyler.load(tiny_multistyle).with_performer_style(READ)


def test_train_reader_keeps_the_generator_and_refuses_a_pair_model(tiny_multistyle, tmp_path, monkeypatch):
    """``stylecast train-reader`` adds the reader beside the generator: every other tensor
    and metadata entry is kept bit for bit."""
    tensors, meta = ckpt.read_checkpoint(tiny_multistyle)
    features = Restyler.load(tiny_multistyle).rep.channels * len(meta["bones"])
    monkeypatch.setattr(style_reader, "train_reader", lambda *a, **k: _reader_tensors(features, "active"))
    out = style_reader.add_reader(tiny_multistyle, tmp_path / "with-reader.safetensors", log=lambda *_: None)
    again, meta_again = ckpt.read_checkpoint(out)
    assert all(np.array_equal(again[k], v) for k, v in tensors.items())
    assert sorted(set(again) - set(tensors)) == sorted(_reader_tensors(features)[0])
    assert {k: v for k, v in meta_again.items() if k not in ("reader", "weights_sha256")} == \
        {k: v for k, v in meta.items() if k != "weights_sha256"}
    words = torch.from_numpy(walk_clip(60).rotations[None])
    assert Restyler.load(out).reader.read(words)[0, STYLES.index("active")] > 0.999
    with pytest.raises(UserError, match="not a multi-style model"):
        style_reader.add_reader("normal2exhausted", tmp_path / "pair.safetensors", log=lambda *_: None)


def test_subnormal_weights_are_flushed_and_the_shipped_reader_has_none():
    """Subnormal floats multiply slowly on x86 (the shipped reader read 64 words in 40 ms
    with 2,017 of them, 5.3 ms without): fitting a classifier (a judge, the reader) flushes
    them to zero, nothing else."""
    tiny = np.finfo(np.float32).tiny
    w = np.array([tiny / 4, -tiny / 2, tiny, 1e-30, -3.0], np.float32)
    np.testing.assert_array_equal(flush_subnormals(w), np.float32([0, 0, tiny, 1e-30, -3.0]))
    tensors, _ = ckpt.read_checkpoint(SHIPPED)
    reader = [v for k, v in tensors.items() if k.startswith(style_reader.PREFIX)]
    assert reader and not any(np.any((v != 0) & (np.abs(v) < tiny)) for v in reader)


SHIPPED = ckpt.CHECKPOINT_DIR / "multistyle.safetensors"
needs_data = pytest.mark.skipif(not (D.default_data_dir().is_dir() and SHIPPED.exists()),
                                reason="needs the shared Bandai data and the shipped multistyle model")
TAKES = 3  # held-out takes of each style


@needs_data
def test_the_shipped_reader_reads_held_out_takes_of_every_style_as_that_style():
    """Each style's held-out takes, cut into words as the daemon cuts them: every style is
    read as itself, none as the others (a reader that read one style for everything, or
    the pose alone, would fail on six of them)."""
    torch.set_num_threads(1)
    reader = Restyler.load("multistyle").reader
    files = D.list_files()
    for k, style in enumerate(STYLES):
        takes = D.load_motions(D.files_for_style(files, style, "val")[:TAKES])
        words = np.concatenate([D.cut_words(m.rotations.astype(np.float64), DEFAULT_HOP) for m in takes])
        p = reader.read(torch.from_numpy(rot.canonical_hemisphere(words, axis=1)))
        assert np.mean(p.argmax(axis=1) == k) >= 0.99 and p[:, k].mean() >= 0.95, (style, p.mean(axis=0))


@needs_data
def test_read_performers_own_style_passes_through_and_another_target_is_restyled_as_if_named():
    """Held-out elderly takes served towards elderly: read, they pass through as performed
    (taken for normal, the default, the code moved them: the known-bad case); towards
    youthful the read style restyles them as the named one does."""
    torch.set_num_threads(1)
    model = Restyler.load("multistyle")
    take = D.load_motions(D.files_for_style(D.list_files(), "elderly", "val")[:1])[0]
    rotations = take.rotations.astype(np.float64)

    def moved(restyler, like=rotations):
        out = restyle_rotations(rotations, restyler.restyle_words, DEFAULT_HOP, live=True).rotations
        return rot.angle_between(out, like)[60:]  # after the stream's first second (its first pose held)

    elderly = model.for_target("elderly")
    assert moved(elderly.with_performer_style(READ)).mean() < 0.05  # degrees a bone
    assert moved(elderly).mean() > 1.0
    youthful = model.for_target("youthful")
    named = restyle_rotations(rotations, youthful.with_performer_style("elderly").restyle_words, DEFAULT_HOP,
                              live=True).rotations
    assert moved(youthful.with_performer_style(READ), named).max() < 0.05
    assert moved(youthful.with_performer_style(READ)).mean() > 1.0
