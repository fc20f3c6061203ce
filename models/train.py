"""Training the CycleGAN restyler (``stylecast train``).

One epoch = ``words_per_epoch`` words of each style, drawn without replacement from the
training words with a generator seeded by (seed, epoch), in batches of ``batch_size``.
The paper's "epoch" is a pass over its 200 s of data per style (~600 words at hop 20);
the Bandai pairs have ~5,000 training words per style, so a sampled epoch of 1,024 words
keeps 90 epochs inside the 20-minute budget on one CPU core. Each step updates the two
generators on (11) (without the discriminator terms), then the two discriminators on
(1)+(2): the usual alternating form of (12). Adam, lr 2e-4, betas (0.5, 0.999).

Files written to the output folder (the loop and the resume state: ``epoch_loop.py``):
  checkpoint.safetensors/.json  all four networks + metadata, rewritten every epoch
  train_state.safetensors/.json optimiser moments, the weight average and the epoch, for --resume
  losses.csv                    one row of mean losses (and validation figures) per epoch
  model.safetensors/.json       the two generators only: the shippable model (their weight
                                average unless --ema 0; the last weights in model-raw.safetensors)

Deterministic on the CPU for a seed: weights come from torch.manual_seed(seed), batches
from numpy's default_rng((seed, epoch)), torch.use_deterministic_algorithms(True). On
CUDA, deterministic wherever torch has a deterministic op; one line names any op that
has none (``device.Determinism``).
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import HUMANOID_BONES, RETARGET_VERSION

from . import checkpoint as ckpt
from . import data as D
from . import losses as L
from .averaging import WeightAverage
from .content import ActionLabels, FrozenClassifier, PositionView
from .holds import HoldTerm
from .position_critic import PREFIX as CRITICS_PREFIX, PositionCritics
from .style_target import STYLE_SALT, StyleWords
from .device import Determinism, pick_device
from .epoch_loop import check_resumable, finish, read_train_state, run_epochs, write_models, write_train_state
from .networks import CycleGAN, NetworkConfig, count_parameters, to_channels
from . import representation as R
from .representation import euler_features, get_representation

GENERATOR_PREFIXES = ("G_a2b.", "G_b2a.")
ACTION_VIEWS = ("channels", "positions")  # what the action-content classifier sees (content.py)
CSV_FIELDS = ("epoch", "seconds", "cpu_seconds", "G_a2b", "G_b2a", "D_a", "D_b", "cycle_a", "cycle_b", "temporal_a",
              "temporal_b", "gram_a2b", "gram_b2a", "overlap_a", "overlap_b", "action_a2b", "action_b2a", "style_a2b",
              "style_b2a", "hold_a2b", "hold_b2a", "position_a2b", "position_b2a", "D_positions", "G_total",
              "val_cycle_a", "val_cycle_b", "val_diff_a", "val_diff_b", "val_smooth_ratio_a2b", "val_smooth_ratio_b2a")


@dataclass
class TrainConfig:
    style_a: str = "normal"
    style_b: str = "exhausted"
    loss: str = "cycle-diff"
    epochs: int = 90
    batch_size: int = 32
    words_per_epoch: int = 1024
    seed: int = 0
    lr: float = 2e-4
    beta1: float = 0.5
    beta2: float = 0.999
    representation: str = "euler"
    centre: bool = False  # centre each bone on its mean rotation (see representation.py)
    hop: int = 20
    max_words: int | None = None
    val_words: int = 256
    mirror: bool = False  # train on the takes and their left-right mirror images (data.with_mirror)
    lambda_cycle: float = L.LAMBDA_CYCLE
    lambda_diff: float = L.LAMBDA_DIFF
    lambda_coherence: float = L.LAMBDA_COHERENCE
    lambda_gram: float = L.LAMBDA_GRAM
    lambda_overlap: float = 0.0  # overlapping words agree (losses.overlap_loss); 0 = off
    lambda_action: float = 0.0  # the restyle keeps the input's action (content.py); 0 = off
    action_view: str = "channels"  # what its classifier sees: the generator's channels or joint positions
    lambda_style: float = 0.0  # the restyle reads as the target among all styles (style_target.py); 0 = off
    lambda_hold: float = 0.0  # where the input holds a hand or the head still, so does the restyle (holds.py); 0 = off
    hold_from: int = 0  # the epochs before it train without the hold term (a fine-tune of a finished run)
    # Weight of a second adversarial term, discriminators over the joints' world positions
    # (position_critic.py); 0 = off.
    lambda_position_adv: float = 0.0
    # The model written is the generators' weight average (averaging.py) with this decay; 0 =
    # the last weights. Measured over four seeds of the pair recipe (MODEL_CARD.md), the
    # average against each run's own last weights: jerk 1.08-1.14 -> 1.01-1.02, planted-foot
    # slide 1.32-1.41 -> 1.10-1.30, timing sync and FMD better in every run, judged exhausted
    # 64/55/78/77 -> 68/84/69/75 %.
    ema: float = 0.999
    # The foot lock ``--feet auto`` serves the model with (motion.footlock.FEET), recorded in
    # the checkpoint; None: its kind's own (``Restyler.default_feet``). It changes no training.
    feet: str | None = None
    network: NetworkConfig = field(default_factory=NetworkConfig)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["network"] = self.network.to_dict()
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "TrainConfig":
        d = dict(d)
        d["network"] = NetworkConfig(**d.get("network", {}))
        return cls(**d)


def build_model(cfg: TrainConfig, reference: np.ndarray | None = None):
    rep = get_representation(cfg.representation, reference)
    net = replace(cfg.network, channels=rep.channels, joints=len(HUMANOID_BONES))
    cfg.network = net
    return CycleGAN(net, rep.combine), rep


def shared_metadata(cfg, rep, styles_trained: str) -> dict:
    """What every stylecast checkpoint records, whatever its kind (``cfg`` has ``network``
    and ``to_dict``): the conventions a loader checks, the training settings, the data and
    its licence."""
    return {
        "bones": list(HUMANOID_BONES),
        "representation": rep.metadata(),
        "normalisation": rep.metadata()["normalisation"],
        "heading": "removed per word (Hips yaw at the centre frame), restored after the generator",
        "fps": D.FPS,
        "word_length": D.WORD_LENGTH,
        "retarget_version": RETARGET_VERSION,
        "network": cfg.network.to_dict(),
        "training": {k: v for k, v in cfg.to_dict().items() if k != "network"},
        "training_data": f"{D.DATA_NAME}: {styles_trained}, training split by file "
                         f"(SHA-1 of file name, {int(D.VAL_FRACTION * 100)}% held out)",
        "licence": f"{D.DATA_LICENCE}: trained on the {D.DATA_NAME} (Kobayashi et al., arXiv:2306.08861); "
                   f"the weights may only be used non-commercially",
        "git_revision": ckpt.git_revision(),
        **({"feet": cfg.feet} if cfg.feet else {}),
    }


def model_metadata(cfg: TrainConfig, rep, extra: dict | None = None) -> dict:
    meta = {
        "styles": {"a": cfg.style_a, "b": cfg.style_b},
        **shared_metadata(cfg, rep, f"styles {cfg.style_a} and {cfg.style_b}"),
        "loss": cfg.loss,
        "lambdas": {"cycle": cfg.lambda_cycle, "diff": cfg.lambda_diff, "coherence": cfg.lambda_coherence,
                    "gram": cfg.lambda_gram, "action": cfg.lambda_action, "style": cfg.lambda_style,
                    "hold": cfg.lambda_hold, "position_adv": cfg.lambda_position_adv},
        "hold_from_epoch": cfg.hold_from,
    }
    meta.update(extra or {})
    return meta


def _batches(n_words: int, wanted: int, batch: int, rng: np.random.Generator) -> list[np.ndarray]:
    reps = math.ceil(wanted / n_words)
    order = np.concatenate([rng.permutation(n_words) for _ in range(reps)])[:wanted]
    return [order[i:i + batch] for i in range(0, wanted, batch)]


def smoothness(features_euler: np.ndarray) -> float:
    """Mean over bones of the per-word sum of d_t (METHOD.md), words (N, T, J, 3)."""
    d = np.linalg.norm(np.diff(features_euler, axis=1), axis=-1)  # (N, T-1, J)
    return float(d.sum(axis=1).mean())


class Trainer:
    """Trains on quaternion words (N, 60, J, 4), heading already removed (``data.headless``).
    The representation's per-bone reference is the mean of both styles' training words."""

    def __init__(self, cfg: TrainConfig, words_a: np.ndarray, words_b: np.ndarray,
                 val_a: np.ndarray | None = None, val_b: np.ndarray | None = None, device: str = "auto",
                 reference: np.ndarray | None = None, next_a: np.ndarray | None = None,
                 next_b: np.ndarray | None = None, actions: ActionLabels | None = None,
                 styles: StyleWords | None = None, skeleton=None):
        """``next_a``/``next_b``: for each training word, the index of the next word of the
        same take (overlapping it by 60 - hop frames), or -1 (``data.next_words``).
        ``actions``: every word's action, needed when ``cfg.lambda_action`` > 0.
        ``styles``: words of every style, needed when ``cfg.lambda_style`` > 0.
        ``skeleton``: the actors' humanoid skeleton, needed with ``cfg.action_view`` "positions",
        ``cfg.lambda_hold`` > 0 and ``cfg.lambda_position_adv`` > 0."""
        import torch

        if cfg.loss not in L.LOSS_KINDS:
            raise UserError(f"unknown loss {cfg.loss!r}; choose cycle-diff or coherence")
        if cfg.action_view not in ACTION_VIEWS:
            raise UserError(f"unknown action view {cfg.action_view!r}; choose {' or '.join(ACTION_VIEWS)}")
        self.skeleton = skeleton
        if len(words_a) == 0 or len(words_b) == 0:
            raise UserError(f"no training words for style {cfg.style_a if len(words_a) == 0 else cfg.style_b}; "
                            f"check the data folder")
        self.cfg = cfg
        self.device = pick_device(device)
        torch.manual_seed(cfg.seed)
        self.determinism = Determinism(self.device)  # exact on the CPU; never raises on CUDA
        if reference is None and cfg.centre:
            reference = R.mean_reference(np.concatenate([words_a[::3], words_b[::3]]))
        self.model, self.rep = build_model(cfg, reference)
        self.model.to(self.device)
        self.critics = None
        if cfg.lambda_position_adv > 0:
            if skeleton is None:
                raise UserError("--lambda-position-adv needs the actors' skeleton; train from the dataset folder")
            self.critics = PositionCritics(cfg.network, self.rep, skeleton, self.device, cfg.seed)
        self.opt_g = torch.optim.Adam(self.model.generators(), lr=cfg.lr, betas=(cfg.beta1, cfg.beta2))
        self.opt_d = torch.optim.Adam(self._discriminators(), lr=cfg.lr, betas=(cfg.beta1, cfg.beta2))
        self.next_a, self.next_b = next_a, next_b
        self.words_a = torch.from_numpy(self._encode(words_a))
        self.words_b = torch.from_numpy(self._encode(words_b))
        if self.critics is not None:  # the real words' positions, once for the run
            self.positions = tuple(self.critics.positions(to_channels(w)) for w in (self.words_a, self.words_b))
        self.val_a = None if val_a is None or len(val_a) == 0 else self._encode(val_a[: cfg.val_words])
        self.val_b = None if val_b is None or len(val_b) == 0 else self._encode(val_b[: cfg.val_words])
        self.epoch = 0  # epochs completed
        self.average = WeightAverage(self.model, GENERATOR_PREFIXES, cfg.ema) if cfg.ema > 0 else None
        self.content = self.actions = None
        if cfg.lambda_action > 0:
            self._fit_content(actions, val_a, val_b)
        self.style_judge = self.style_targets = None
        if cfg.lambda_style > 0:
            self._fit_style(styles)
        self.hold = None
        if cfg.lambda_hold > 0:
            if skeleton is None:
                raise UserError("--lambda-hold needs the actors' skeleton; train from the dataset folder")
            self.hold = HoldTerm(self.rep, skeleton, self.device)

    def _fit_content(self, actions: ActionLabels | None, val_a, val_b) -> None:
        """Train the frozen action classifier of the content loss on both styles' training
        words, and score it on their held-out words."""
        import torch

        if actions is None:
            raise UserError("--lambda-action needs the action of every training word; train from the dataset folder")
        x = torch.cat([self._channels(self.words_a), self._channels(self.words_b)])
        view = None
        if self.cfg.action_view == "positions":
            if self.skeleton is None:
                raise UserError("--action-view positions needs the actors' skeleton; train from the dataset folder")
            view = PositionView(self.rep, self.skeleton, self.device)
        self.content = FrozenClassifier(actions.classes, view.features if view else x.shape[1], self.cfg.seed,
                                        view=view).fit(
            x, np.concatenate([actions.train[self.cfg.style_a], actions.train[self.cfg.style_b]]), self.device)
        if val_a is not None and val_b is not None and len(val_a) and len(val_b):
            self.content.score("val", torch.cat([self._channels(val_a), self._channels(val_b)]),
                               np.concatenate([actions.val[self.cfg.style_a], actions.val[self.cfg.style_b]]),
                               self.device)
        self.actions = tuple(torch.from_numpy(actions.train[s]) for s in (self.cfg.style_a, self.cfg.style_b))

    def _fit_style(self, styles: StyleWords | None) -> None:
        """Train the frozen seven-style classifier of the style loss on training words of
        every style, and score it on their held-out words."""
        import torch

        cfg = self.cfg
        if styles is None or cfg.style_a not in styles.classes or cfg.style_b not in styles.classes:
            raise UserError("--lambda-style needs training words of every style; train from the dataset folder")
        words, labels = styles.labelled("train")
        x = torch.cat([self._channels(w) for w in words])
        self.style_judge = FrozenClassifier(list(styles.classes), x.shape[1], cfg.seed, STYLE_SALT).fit(
            x, labels, self.device)
        words, labels = styles.labelled("val")
        if len(labels):
            self.style_judge.score("val", torch.cat([self._channels(w) for w in words]), labels, self.device)
        # The targets of G_a2b and G_b2a, as 0-d tensors a batch's labels expand from.
        self.style_targets = tuple(torch.tensor(styles.classes.index(s), device=self.device)
                                   for s in (cfg.style_b, cfg.style_a))

    def _discriminators(self) -> list:
        """Every discriminator's parameters (one optimiser): the paper's two, and the position
        critics' when they train."""
        extra = list(self.critics.parameters()) if self.critics is not None else []
        return self.model.discriminators() + extra

    def _channels(self, words):
        """Channel words (N, F, T) on the CPU from quaternion words or encoded tensors."""
        import torch

        return to_channels(words if torch.is_tensor(words) else torch.from_numpy(self._encode(words)))

    # -- one step ---------------------------------------------------------------------
    def step(self, a, b, a_next=None, b_next=None, a_actions=None, b_actions=None,
             positions=None) -> dict[str, float]:
        """One update. ``a_next``/``b_next``: (rows, next words) pairs, the word after each
        of those rows of ``a``/``b`` in the same take (for the overlap loss), or None.
        ``a_actions``/``b_actions``: the words' actions (for the content loss), or None.
        ``positions``: the joint positions of ``a`` and ``b`` (for the position critics), or None."""
        m, cfg = self.model, self.cfg
        for p in self._discriminators():
            p.requires_grad_(False)
        fake_b = m.G_a2b(a)
        fake_a = m.G_b2a(b)
        rec_a = m.G_b2a(fake_b)
        rec_b = m.G_a2b(fake_a)
        g = L.generator_objective(cfg.loss, a, b, fake_b, fake_a, rec_a, rec_b, m.D_b(fake_b), m.D_a(fake_a),
                                  cfg.lambda_cycle, cfg.lambda_diff, cfg.lambda_coherence, cfg.lambda_gram)
        total = g.total
        extras = {}  # the optional terms' values, 0 when off
        for name, fake, nxt, gen in (("overlap_a", fake_b, a_next, m.G_a2b), ("overlap_b", fake_a, b_next, m.G_b2a)):
            if cfg.lambda_overlap > 0 and nxt is not None and len(nxt[0]):
                rows, words = nxt
                loss = L.overlap_loss(fake[rows], gen(words), cfg.hop, self.rep.channels)
                total = total + cfg.lambda_overlap * loss
                extras[name] = loss.item()
            else:
                extras[name] = 0.0
        for name, fake, actions in (("action_a2b", fake_b, a_actions), ("action_b2a", fake_a, b_actions)):
            if self.content is not None and actions is not None:
                loss = self.content.loss(fake, actions)
                total = total + cfg.lambda_action * loss
                extras[name] = loss.item()
            else:
                extras[name] = 0.0
        for name, fake, target in zip(("style_a2b", "style_b2a"), (fake_b, fake_a), self.style_targets or (None, None)):
            if target is not None:
                loss = self.style_judge.loss(fake, target.expand(len(fake)))
                total = total + cfg.lambda_style * loss
                extras[name] = loss.item()
            else:
                extras[name] = 0.0
        for name, fake, given in (("hold_a2b", fake_b, a), ("hold_b2a", fake_a, b)):
            if self.hold is not None and self.epoch >= cfg.hold_from:
                loss = self.hold(fake, given)
                total = total + cfg.lambda_hold * loss
                extras[name] = loss.item()
            else:
                extras[name] = 0.0
        extras["position_a2b"] = extras["position_b2a"] = extras["D_positions"] = 0.0
        if self.critics is not None:
            adv_a2b, adv_b2a, fake_b_positions, fake_a_positions = self.critics.generator_losses(fake_b, fake_a)
            total = total + cfg.lambda_position_adv * (adv_a2b + adv_b2a)
            extras["position_a2b"], extras["position_b2a"] = adv_a2b.item(), adv_b2a.item()
        self.opt_g.zero_grad(set_to_none=True)
        total.backward()
        self.opt_g.step()
        if self.average is not None:
            self.average.update(m)
        for p in self._discriminators():
            p.requires_grad_(True)
        d_a = L.discriminator_loss(m.D_a(a), m.D_a(fake_a.detach()))
        d_b = L.discriminator_loss(m.D_b(b), m.D_b(fake_b.detach()))
        d_total = d_a + d_b
        if self.critics is not None:
            d_positions = self.critics.loss(*positions, fake_a_positions, fake_b_positions)
            d_total = d_total + d_positions
            extras["D_positions"] = d_positions.item()
        self.opt_d.zero_grad(set_to_none=True)
        d_total.backward()
        self.opt_d.step()
        return {"G_a2b": g.adv_a2b.item(), "G_b2a": g.adv_b2a.item(), "D_a": d_a.item(), "D_b": d_b.item(),
                "cycle_a": g.cycle_a.item(), "cycle_b": g.cycle_b.item(), "temporal_a": g.temporal_a.item(),
                "temporal_b": g.temporal_b.item(), "gram_a2b": g.gram_a2b.item(), "gram_b2a": g.gram_b2a.item(),
                **extras, "G_total": total.item()}

    def _to(self, words):
        return to_channels(words).to(self.device)

    def _next(self, nxt, words, rows):
        """(rows of the batch that have a next word, those next words) for the overlap loss."""
        if nxt is None or self.cfg.lambda_overlap <= 0:
            return None
        import torch

        following = nxt[rows]
        keep = np.flatnonzero(following >= 0)
        return torch.from_numpy(keep).to(self.device), self._to(words[following[keep]])

    def _actions(self, ia, ib):
        """The batch's actions for the content loss, or (None, None) when it is off."""
        if self.actions is None:
            return None, None
        return self.actions[0][ia].to(self.device), self.actions[1][ib].to(self.device)

    def _positions(self, ia, ib):
        """The batch's real joint positions for the position critics, or None when they are off."""
        if self.critics is None:
            return None
        return self.positions[0][ia].to(self.device), self.positions[1][ib].to(self.device)

    def run_epoch(self, progress=None) -> dict[str, float]:
        cfg = self.cfg
        self.model.train()
        rng = np.random.default_rng((cfg.seed, self.epoch))
        ba = _batches(len(self.words_a), cfg.words_per_epoch, cfg.batch_size, rng)
        bb = _batches(len(self.words_b), cfg.words_per_epoch, cfg.batch_size, rng)
        sums: dict[str, float] = {}
        for i, (ia, ib) in enumerate(zip(ba, bb)):
            with self.determinism.watch():
                out = self.step(self._to(self.words_a[ia]), self._to(self.words_b[ib]),
                                self._next(self.next_a, self.words_a, ia), self._next(self.next_b, self.words_b, ib),
                                *self._actions(ia, ib), self._positions(ia, ib))
            for k, v in out.items():
                sums[k] = sums.get(k, 0.0) + v
            if progress is not None:
                progress.update(1)
                progress.set_postfix({k: f"{sums[k] / (i + 1):.3g}" for k in ("G_a2b", "D_b", "cycle_a", "temporal_a")})
        self.epoch += 1
        return {k: v / len(ba) for k, v in sums.items()}

    def validate(self) -> dict[str, float]:
        import torch

        out: dict[str, float] = {}
        if self.val_a is None or self.val_b is None:
            return out
        self.model.eval()
        with torch.no_grad():
            for name, words, g, back in (("a", self.val_a, self.model.G_a2b, self.model.G_b2a),
                                         ("b", self.val_b, self.model.G_b2a, self.model.G_a2b)):
                x = self._to(torch.from_numpy(np.ascontiguousarray(words, dtype=np.float32)))
                y = g(x)
                rec = back(y)
                out[f"val_cycle_{name}"] = L.cycle_loss(rec, x).item()
                out[f"val_diff_{name}"] = L.diff_loss(rec, x).item()
                y_words = y.transpose(1, 2).reshape(words.shape).cpu().numpy()
                e_in = self._euler(words)
                e_out = self._euler(y_words)
                key = "a2b" if name == "a" else "b2a"
                out[f"val_smooth_ratio_{key}"] = smoothness(e_out) / max(smoothness(e_in), 1e-12)
        return out

    def _encode(self, words: np.ndarray, chunk: int = 2048) -> np.ndarray:
        out = np.empty((*words.shape[:3], self.rep.channels), np.float32)
        for i in range(0, len(words), chunk):
            out[i:i + chunk] = self.rep.encode(words[i:i + chunk])
        return out

    def _euler(self, features: np.ndarray) -> np.ndarray:
        if self.rep.name == "euler":
            return features
        return euler_features(self.rep.decode(features), self.rep.reference)

    # -- state ------------------------------------------------------------------------
    def model_tensors(self, generators_only: bool = False) -> dict:
        sd = self.model.state_dict()
        if generators_only:
            return {k: v for k, v in sd.items() if k.startswith(GENERATOR_PREFIXES)}
        if self.critics is not None:
            sd.update({CRITICS_PREFIX + k: v for k, v in self.critics.state_dict().items()})
        return sd

    def save(self, out: Path, metrics: dict | None = None) -> None:
        meta = model_metadata(self.cfg, self.rep, {"epochs_completed": self.epoch, "metrics": metrics or {}})
        ckpt.save_checkpoint(out / "checkpoint.safetensors", self.model_tensors(), meta)
        write_train_state(out, self, meta)

    def load_state(self, out: Path) -> None:
        read_train_state(out, self, TrainConfig, ("G_", "D_"))
        if self.critics is not None:
            path = out / "checkpoint.safetensors"
            tensors, _ = ckpt.read_checkpoint(path)
            mine = {k[len(CRITICS_PREFIX):]: v for k, v in tensors.items() if k.startswith(CRITICS_PREFIX)}
            self.critics.load_state_dict(ckpt.check_shapes(path, self.critics, mine, ("D_",)))


def train(cfg: TrainConfig, out: Path, words_a, words_b, val_a=None, val_b=None, resume: bool = False,
          device: str = "auto", progress: bool = True, log=print, next_a=None, next_b=None,
          actions: ActionLabels | None = None, styles: StyleWords | None = None, skeleton=None) -> Trainer:
    """Train (or resume) into folder ``out``; returns the trainer (model at the last epoch)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    reference = None
    if resume:
        check_resumable(out)
        _, meta = ckpt.read_checkpoint(out / "checkpoint.safetensors")
        ref = meta["representation"].get("reference")
        reference = None if ref is None else np.asarray(ref, dtype=np.float64)
    trainer = Trainer(cfg, words_a, words_b, val_a, val_b, device, reference, next_a, next_b, actions, styles,
                      skeleton)
    trainer.determinism.log = log
    if trainer.content is not None:
        log(f"action-content classifier: {len(trainer.content.classes)} actions, right on "
            f"{trainer.content.accuracy.get('val', float('nan')):.1%} of held-out words of both styles")
    if trainer.style_judge is not None:
        log(f"style classifier: {len(trainer.style_judge.classes)} styles, right on "
            f"{trainer.style_judge.accuracy.get('val', float('nan')):.1%} of held-out words of every style")
    g = count_parameters(trainer.model.G_a2b)
    log(f"training {cfg.style_a}<->{cfg.style_b} ({cfg.loss}, {cfg.representation}) on {trainer.device}: "
        f"{len(words_a)}/{len(words_b)} training words, {cfg.words_per_epoch} per epoch, generator {g} parameters")
    final = run_epochs(trainer, out, math.ceil(cfg.words_per_epoch / cfg.batch_size), CSV_FIELDS, resume, progress,
                       log)
    extra = {"epochs_completed": trainer.epoch, "metrics": final}
    if trainer.content is not None:
        extra["action_content_accuracy"] = trainer.content.accuracy
    if trainer.style_judge is not None:
        extra["style_classifier_accuracy"] = trainer.style_judge.accuracy
    meta = model_metadata(cfg, trainer.rep, extra)
    write_models(out, trainer.model_tensors(generators_only=True), trainer.average, lambda _: meta, log)
    finish(out, cfg, final, log)
    return trainer


def load_training_words(cfg: TrainConfig, data_dir=None, cache_dir=None, progress: bool = True, log=print):
    """Heading-free quaternion words of both styles, training and validation splits."""
    t0 = time.perf_counter()
    sets = {}
    for style in (cfg.style_a, cfg.style_b):
        for split in ("train", "val"):
            cap = cfg.max_words if split == "train" else (cfg.val_words if cfg.max_words is None else
                                                          min(cfg.val_words, cfg.max_words))
            # Held-out words stay as recorded: validation figures compare across recipes.
            sets[(style, split)] = D.load_wordset(style, split, data_dir, cache_dir, cfg.hop, cap, progress,
                                                  mirror=cfg.mirror and split == "train")
    log(f"loaded words in {time.perf_counter() - t0:.1f} s: " + ", ".join(
        f"{s}/{sp} {len(w)}" for (s, sp), w in sets.items()))
    return sets
