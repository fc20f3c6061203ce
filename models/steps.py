"""The step term (``train --styles all --lambda-step``): a restyle may not lift the feet
higher than the target style lifts them.

Why: the evaluation's step height (``metrics.step_heights``) found the multistyle model's
elderly walks stepping 1.32x as high as the input's, where real elderly walks step 0.79x
as high as real normal ones (towards exhausted 1.14x against 0.99x). The generator does it
itself: without the foot lock its elderly ankles rose 20.3 cm against the input's 14.0 and
real elderly's 11.0 (MODEL_CARD.md, "How high the feet step"). A high-stepping old man reads
wrong to any viewer, and neither the discriminator nor the cycle can see it: a word's
channels carry no height.

What it is: forward kinematics of both ankles against the hips (``content.PositionView``),
each word's step height on the evaluation's definition (the 98th percentile of the ankle's
height over its 5th, ``metrics.STEP_PERCENTILES``), and, for a word of style s sent to t, the
height its restyle steps above ``ratio[a, s, t]`` times the input's, plus ``SLACK`` cm, in cm
(0 below it). ``ratio[a, s, t]`` is the mean step height of style t's training words of the
word's action a over style s's (dataset-2 records every action in every style), so the cap
is learned from the data, not chosen: an elderly walk may step as high as elderly walks do
against normal ones, an elderly run as elderly runs do. Steps lower than the cap are free:
the term only stops a restyle stepping higher than its target style would. Heights are
taken against the hips, as a word carries no root; the evaluation's are in the world.

Measured (MODEL_CARD.md, "A step term"), in training and as ``tune_steps`` on the shipped
file: the steps come right (towards elderly, walks 1.32 -> 0.97x the input's), but every
target's steps fall, not only those above their cap, and the judges read five of six styles
weaker. Off by default, and the shipped file is not tuned.
"""

from __future__ import annotations

import torch

from stylecast.motion.humanoid import HUMANOID_BONES

from .content import CM, PositionView
from .metrics import STEP_JOINTS, STEP_PERCENTILES

# Free height above the cap, in cm: a foot that stays on the floor "steps" a centimetre or
# two by the hips' sway, and a ratio of that is noise, not a step.
SLACK = 1.0
CHUNK = 512  # words per forward-kinematics call when measuring the training words


class StepTerm:
    """The term for a batch of channel words, in cm (0 when no restyle steps above its cap)."""

    def __init__(self, representation, skeleton, device, words: list[torch.Tensor], actions: list[torch.Tensor],
                 classes: int):
        """``words``: each style's training words in channels (N, F, T), in ``STYLES``
        order, and ``actions`` their actions (N,) (indices below ``classes``), to learn the
        caps from."""
        self.view = PositionView(representation, skeleton, device,
                                 joints=tuple(HUMANOID_BONES.index(j) for j in STEP_JOINTS))
        mean = torch.full((classes, len(words)), float("nan"))
        with torch.no_grad():
            for k, (w, a) in enumerate(zip(words, actions)):
                h = torch.cat([self.heights(w[i:i + CHUNK].to(device)) for i in range(0, len(w), CHUNK)]).mean(1).cpu()
                for c in range(classes):
                    if (a == c).any():
                        mean[c, k] = h[a == c].mean()
        self.heights_per_action = mean  # (A, S) cm: each action's mean step height in each style (nan: no words)
        ratio = mean[:, None, :] / mean[:, :, None]  # ratio[a, s, t]: t's steps over s's
        # An action missing from either style's words (a subset of the data) has no cap.
        self.ratio = torch.nan_to_num(ratio, nan=float("inf")).to(device)

    def heights(self, x: torch.Tensor) -> torch.Tensor:
        """Channel words (B, F, T) -> (B, 2) each ankle's step height in the word, cm."""
        p = self.view(x)
        y = CM * p.reshape(p.shape[0], -1, 3, p.shape[-1])[:, :, 1]  # (B, 2, T) height against the hips
        q = torch.tensor([v / 100.0 for v in STEP_PERCENTILES], dtype=y.dtype, device=y.device)
        low, high = torch.quantile(y, q, dim=-1)
        return high - low

    def __call__(self, restyled: torch.Tensor, source: torch.Tensor, action: torch.Tensor, src: torch.Tensor,
                 tgt: torch.Tensor) -> torch.Tensor:
        """``restyled``, ``source``: channel words (B, F, T), the generator's output and
        input; ``action``, ``src``, ``tgt``: the input's action and style and the target
        style, indices (B,)."""
        with torch.no_grad():
            cap = self.ratio[action, src, tgt][:, None] * self.heights(source) + SLACK
        return torch.relu(self.heights(restyled) - cap).mean()


# --- tuning a finished multi-style model (``stylecast tune-steps``) --------------------------------

BATCH = 32
STEP_TUNE_EPOCHS = 4  # passes over every style's training words
STEP_TUNE_LR = 1e-4
STEP_TUNE_STEP = 1.0
# The weight of the distillation, L1 on the channels against the model as it was (as
# ``holds.HOLD_TUNE_DISTIL``, whose measure chose 100 for the pair model's holds).
STEP_TUNE_DISTIL = 100.0


def tune_steps(model, out, *, lambda_step: float = STEP_TUNE_STEP, distil: float = STEP_TUNE_DISTIL,
               epochs: int = STEP_TUNE_EPOCHS, lr: float = STEP_TUNE_LR, seed: int = 1, data_dir=None,
               cache_dir=None, max_words: int | None = None, log=print):
    """Tune a finished multi-style model so its restyles step no higher than their target
    style's (``StepTerm``), and change nothing else they can help: the generator learns
    ``distil * |G(x, t) - G_before(x, t)| + lambda_step * step(G(x, t), x)`` over every
    style's training words, each sent to a target drawn uniformly from the other styles,
    Adam from the model's own weights. Why not the term in the GAN's training (``train
    --lambda-step``): there it fixed the steps but came out another GAN than the shipped
    draw, reading weaker as most styles; the distillation keeps the one that was chosen.
    Measured on the shipped file (MODEL_CARD.md, "A step term"): the steps come right
    (towards elderly, walks 1.32 -> 0.97x the input's) but the judges read most styles
    weaker (exhausted 88 -> 63 % on the worst judge), so the shipped file is not tuned.
    ``max_words``: at most that many words of each style (tests). Writes ``out``
    (.safetensors) with every other tensor (the style reader) and entry of the model as it
    was."""
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
        raise UserError(f"checkpoint {path} is not a multi-style model; tune-steps tunes one (multistyle or a "
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
    term = StepTerm(rep, D.bandai_skeleton(D.list_files(data_dir)), "cpu", words, actions, len(labels.classes))
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
            kept, step = (y - before).abs().mean(), term(y, x, a, src, tgt)
            loss = distil * kept + lambda_step * step
            opt.zero_grad()
            loss.backward()
            opt.step()
            sums += (kept.item(), step.item())
            steps += 1
        log(f"epoch {epoch + 1}/{epochs}: distillation {sums[0] / steps:.5f}, step {sums[1] / steps:.4f} cm")
    tuned = {prefix + k: v.detach().numpy() for k, v in student.state_dict().items()}
    kept_tensors = {k: v for k, v in tensors.items() if not k.startswith(prefix)}
    settings = {"from": str(model), "from_weights_sha256": meta.get("weights_sha256"),
                "git_revision": ckpt.git_revision(), "lambda_step": lambda_step, "distil": distil, "epochs": epochs,
                "lr": lr, "seed": seed, "batch": BATCH,
                "last_epoch": {"distillation": sums[0] / steps, "step_cm": sums[1] / steps}}
    out = Path(out)
    ckpt.save_checkpoint(out, {**kept_tensors, **tuned},
                         {**meta, "lambdas": {**meta.get("lambdas", {}), "step": lambda_step}, "step_tuning": settings,
                          "weights": f"{meta.get('weights', 'the trained weights')}, then tuned to step as the "
                                     f"target style does (stylecast tune-steps)"})
    log(f"wrote {out} in {(time.perf_counter() - t0) / 60:.1f} min ({(time.process_time() - c0) / 60:.1f} CPU min)")
    return out
