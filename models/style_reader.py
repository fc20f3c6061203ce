"""The performer's style, read from their motion: ``--performer-style auto``.

A multi-style model is told only the target style; the share of a mix that is the
performer's own style is the input as performed (``restyler_multistyle.code_and_intensity``).
A performer who does not name their style (``--performer-style NAME``) can have it read:
a 7-style classifier over each word the generator is about to restyle, seeing what the
generator sees (the word's heading-free features in the model's representation, poses and
velocities), stored in the multi-style checkpoint beside the generator (tensors
``reader.*``, metadata ``reader``) by ``stylecast train-reader``. The evaluation's style
judges read world joint positions with the root's path instead: the reader is not one of
them, and a restyle tuned on it would not be tuned on them.

Its probabilities enter as they are, not as a decision: the overlap of the mix and the
reading is passed through (``code_and_intensity``), so a word read half elderly half normal
keeps half of an elderly target's correction, and a reading that wavers between two words
moves the correction by as much as it wavers, never by a flip.
"""

from __future__ import annotations

import numpy as np

from stylecast.motion.errors import UserError

from .classifier import WordClassifier
from .styles import STYLES

PREFIX = "reader."
DESIGN = "conv"  # the judges' convolutional design (``classifier.DESIGNS``)
HOP = 20  # training words start every HOP frames, as the generator's training words do
EPOCHS = 12
HELD_OUT_HOP = 15  # the held-out words recorded in the checkpoint start every quarter word


class StyleReader:
    """A trained reader: ``read(words)`` -> each word's style probabilities (B, S)."""

    def __init__(self, net, trep):
        from .networks import batch_invariant

        self.net = batch_invariant(net.eval())  # a word's reading must not depend on its batch
        self.trep = trep  # the model's representation in torch (``representation_torch``)

    @classmethod
    def from_checkpoint(cls, path, tensors: dict, meta: dict, trep) -> "StyleReader | None":
        """The reader stored in a checkpoint's tensors, or None where it has none."""
        from .checkpoint import check_shapes

        info = meta.get("reader")
        if info is None:
            return None
        if not (isinstance(info, dict) and info.get("styles") == list(STYLES) and info.get("design") == DESIGN):
            raise UserError(f"checkpoint {path} has a style reader this stylecast cannot read (it reads "
                            f"{', '.join(STYLES)} with the {DESIGN} design); add it again with "
                            f"`stylecast train-reader --model {path}`")
        classifier = WordClassifier(list(STYLES), trep.channels * len(meta["bones"]), design=DESIGN)
        state = check_shapes(path, classifier.net, {k[len(PREFIX):]: v for k, v in tensors.items()
                                                    if k.startswith(PREFIX)}, ("",))
        classifier.net.load_state_dict(state)
        classifier.net.to(trep.device)
        return cls(classifier.net, trep)

    def read(self, words) -> np.ndarray:
        """Quaternion words (B, 60, J, 4), a float64 tensor on the model's device -> each
        word's style probabilities, (B, S) float32 numpy."""
        from . import pipeline

        p = pipeline.read_styles(self.net, self.trep, words)
        return p.numpy() if p.device.type == "cpu" else p.cpu().numpy()


def train_reader(rep, data_dir=None, cache_dir=None, seed: int = 0, epochs: int = EPOCHS, log=print) -> tuple:
    """A reader for the representation ``rep``, trained on the training split of every
    style (with mirror images) -> (tensors ``reader.*``, metadata ``reader``). Its accuracy
    on the held-out files' words, cut every ``HELD_OUT_HOP`` frames, is in the metadata."""
    from . import data as D

    def features_of(split: str, hop: int, mirror: bool):
        sets = [D.load_wordset(s, split, data_dir, cache_dir, hop=hop, mirror=mirror) for s in STYLES]
        x = np.concatenate([s.features(rep) for s in sets])
        y = np.concatenate([np.full(len(s), k) for k, s in enumerate(sets)])
        return x, y

    x, y = features_of("train", HOP, True)
    log(f"training the style reader on {len(x)} training words of {len(STYLES)} styles (seed {seed})")
    classifier = WordClassifier(list(STYLES), x.shape[2] * x.shape[3], seed, design=DESIGN).fit(x, y, epochs)
    xv, yv = features_of("val", HELD_OUT_HOP, False)
    guess = classifier.predict(xv)
    per_style = {s: round(float(np.mean(guess[yv == k] == k)), 4) for k, s in enumerate(STYLES)}
    log("held-out words read right: " + ", ".join(f"{s} {100 * a:.1f} %" for s, a in per_style.items()))
    tensors = {PREFIX + k: v.detach().cpu().numpy() for k, v in classifier.net.state_dict().items()}
    meta = {"styles": list(STYLES), "design": DESIGN, "seed": seed, "epochs": epochs, "hop": HOP,
            "training_words": int(len(x)), "held_out_words": int(len(xv)),
            "held_out_accuracy": round(float(np.mean(guess == yv)), 4), "held_out_accuracy_per_style": per_style}
    return tensors, meta


def add_reader(model, out=None, seed: int = 0, data_dir=None, cache_dir=None, epochs: int = EPOCHS,
               log=print):
    """``stylecast train-reader``: the multi-style checkpoint ``model`` (a file or a shipped
    name) written to ``out`` (default: in place) with a newly trained reader; its generator's
    tensors and every other entry are kept as they were, a reader it had is replaced."""
    import time

    from . import checkpoint as ckpt
    from .restyler import read_model
    from .restyler_multistyle import KIND

    path = ckpt.resolve(model)
    tensors, meta, rep = read_model(path)
    if meta.get("kind") != KIND:
        raise UserError(f"model {path} is not a multi-style model, and only one reads the performer's style; "
                        f"pass --model multistyle or a model trained with `stylecast train --styles all`")
    start = time.perf_counter()
    reader_tensors, info = train_reader(rep, data_dir, cache_dir, seed, epochs, log)
    info["training_seconds"] = round(time.perf_counter() - start, 1)
    kept = {k: v for k, v in tensors.items() if not k.startswith(PREFIX)}
    target = ckpt.save_checkpoint(out or path, {**kept, **reader_tensors}, {**meta, "reader": info})
    log(f"wrote {target} with its style reader ({info['training_seconds']:.0f} s)")
    return target

