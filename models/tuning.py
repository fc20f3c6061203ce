"""Tuning a finished multi-style model against one term, distilled to the model as it was
(``stylecast tune-steps``, and ``tune-holds`` on a multi-style model).

The generator learns ``distil * |G(x, t) - G_before(x, t)| + weight * term(G(x, t), x, ...)``
over every style's training words, each sent to a target drawn uniformly from the other
styles, Adam from the model's own weights. Why not the term in the GAN's training: there a
term fixes what it measures but the run comes out another GAN than the shipped draw (the
model card, "A step term"); the distillation keeps the one that was chosen.
"""

from __future__ import annotations

from collections.abc import Callable

import torch

BATCH = 32
TUNE_LR = 1e-4

# A term's maker: (representation, skeleton, words, actions, classes) -> the term, called as
# ``term(restyled, source, action, src, tgt)`` on channel words (B, F, T) and indices (B,).
TermMaker = Callable[..., Callable[..., torch.Tensor]]


def distilled_step(opt, restyled: torch.Tensor, before: torch.Tensor, value: torch.Tensor, distil: float,
                   weight: float) -> tuple[float, float]:
    """One step of ``opt`` on ``distil * |restyled - before| + weight * value`` (the term's
    value on the batch): the distillation and the term, as floats."""
    kept = (restyled - before).abs().mean()
    loss = distil * kept + weight * value
    opt.zero_grad()
    loss.backward()
    opt.step()
    return kept.item(), value.item()


def tune_multistyle(model, out, make_term: TermMaker, *, term: str, weight: float, distil: float, epochs: int,
                    seed: int, command: str, what: str, lr: float = TUNE_LR, data_dir=None, cache_dir=None,
                    max_words: int | None = None, log=print):
    """Tune the multi-style checkpoint ``model`` (a file or a shipped name) against the term
    ``make_term`` builds, named ``term`` (its weight ``weight``) in the file's lambdas and in
    the log; ``command`` (the CLI's name) and ``what`` (what the tuning does, for the file's
    "weights" entry) describe it. ``max_words``: at most that many words of each style
    (tests). Writes ``out`` (.safetensors) with every other tensor (the style reader) and
    entry of the model as it was."""
    import copy
    import time
    from pathlib import Path

    import numpy as np

    from stylecast.motion.errors import UserError

    from . import checkpoint as ckpt
    from . import data as D
    from .content import ActionLabels
    from .multistyle import MultiStyleConfig, make_generator
    from .networks import to_channels
    from .restyler import build_checked, network_config, read_model
    from .restyler_multistyle import KIND
    from .styles import STYLES

    t0, c0 = time.perf_counter(), time.process_time()
    path = ckpt.resolve(model)
    tensors, meta, rep = read_model(path)
    if meta.get("kind") != KIND:
        raise UserError(f"checkpoint {path} is not a multi-style model; {command} tunes one (multistyle or a "
                        f"`stylecast train --styles all` output)")
    cfg = network_config(path, meta, MultiStyleConfig)
    prefix = "G."
    student = build_checked(path, {k[len(prefix):]: v for k, v in tensors.items() if k.startswith(prefix)}, rep, cfg,
                            lambda: make_generator(cfg, rep.combine), ("",))
    teacher = copy.deepcopy(student).eval().requires_grad_(False)
    student.train()
    hop = int(meta.get("training", {}).get("hop", 20))
    sets = {(s, "train"): D.load_wordset(s, "train", data_dir, cache_dir, hop, max_words) for s in STYLES}
    labels = ActionLabels.of(sets)
    words = [to_channels(torch.from_numpy(sets[s, "train"].features(rep))) for s in STYLES]
    actions = [torch.from_numpy(labels.train[s]) for s in STYLES]
    loss_of = make_term(rep, D.bandai_skeleton(D.list_files(data_dir)), words, actions, len(labels.classes))
    codes = torch.eye(len(STYLES))
    opt = torch.optim.Adam(student.parameters(), lr=lr, betas=(0.5, 0.999))
    rng = np.random.default_rng(seed)
    style_of = np.concatenate([np.full(len(w), k) for k, w in enumerate(words)])
    index = np.concatenate([np.arange(len(w)) for w in words])
    for epoch in range(epochs):
        order, sums, steps = rng.permutation(len(style_of)), np.zeros(2), 0
        targets = (style_of + rng.integers(1, len(STYLES), size=len(style_of))) % len(STYLES)  # any other style
        for i in range(0, len(order) - BATCH + 1, BATCH):
            b = order[i:i + BATCH]
            src, tgt = torch.from_numpy(style_of[b]), torch.from_numpy(targets[b])
            x = torch.stack([words[k][j] for k, j in zip(style_of[b], index[b])])
            a = torch.stack([actions[k][j] for k, j in zip(style_of[b], index[b])])
            with torch.no_grad():
                before = teacher(x, codes[tgt])
            y = student(x, codes[tgt])
            sums += distilled_step(opt, y, before, loss_of(y, x, a, src, tgt), distil, weight)
            steps += 1
        log(f"epoch {epoch + 1}/{epochs}: distillation {sums[0] / steps:.5f}, {term} {sums[1] / steps:.4f}")
    tuned = {prefix + k: v.detach().numpy() for k, v in student.state_dict().items()}
    kept_tensors = {k: v for k, v in tensors.items() if not k.startswith(prefix)}
    settings = {"from": str(model), "from_weights_sha256": meta.get("weights_sha256"),
                "git_revision": ckpt.git_revision(), f"lambda_{term}": weight, "distil": distil, "epochs": epochs,
                "lr": lr, "seed": seed, "batch": BATCH,
                "last_epoch": {"distillation": sums[0] / steps, term: sums[1] / steps}}
    out = Path(out)
    ckpt.save_checkpoint(out, {**kept_tensors, **tuned},
                         {**meta, "lambdas": {**meta.get("lambdas", {}), term: weight}, f"{term}_tuning": settings,
                          "weights": f"{meta.get('weights', 'the trained weights')}, then tuned {what} "
                                     f"(stylecast {command})"})
    log(f"wrote {out} in {(time.perf_counter() - t0) / 60:.1f} min ({(time.process_time() - c0) / 60:.1f} CPU min)")
    return out
