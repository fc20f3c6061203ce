"""``Restyler``: a loaded model as a batch function on quaternion words.

    r = Restyler.load()                       # models/checkpoints/normal2exhausted, a2b
    r = Restyler.load("runs/x/model.safetensors", direction="b2a")
    out = r.restyle_words(words)              # (B, 60, 22, 4) xyzw -> same shape

One call is one batched forward pass under ``torch.no_grad`` on the model's device
(``--device``): heading removal, encoding, generator, decoding, heading restoration and
the hemisphere fix all run in torch (``representation_torch``), vectorised over the
batch, with no per-word Python or numpy, as one traced graph (``pipeline``: one release
of the GIL per call, so a busy thread beside it cannot stall it op by op). Numpy words
in give numpy words out; a torch tensor stays a tensor (on the model's device). ``restyle_words_numpy`` is the numpy
reference path the tests compare against. The stream code (``stylecast.motion.words``)
calls ``restyle_words`` once per batch of words and blends in numpy.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from stylecast.motion.clock import OUTPUT_FPS as FPS  # the one definition of the frame rate
from stylecast.motion.errors import UserError
from stylecast.motion.footlock import FEET, NO_AMPLITUDES
from stylecast.motion.humanoid import HUMANOID_BONES, RETARGET_VERSION
from stylecast.motion.words import WORD_LENGTH  # the one definition of a word's length

from . import checkpoint as ckpt
from . import representation as R
from .device import pick_device
from .styles import READ

MAX_NETWORK_SIZE = 1 << 16  # no width, depth or kernel of a live restyler comes near this


class Restyler:
    default_feet = "input"  # the foot lock of a pair model whose checkpoint names none (``feet``)
    # A stream's first frame shown restyled (``words.BlendSettings.start_restyled``): the
    # default's live-from-start reading rose to the running stream's, its start pops did not
    # (the model card, "A stream's first frame, restyled").
    start_restyled = True
    # The correction's low-pass (``words.BlendSettings.correction_tau``, frames). A triple
    # pole lags the correction by 3 / (e^(1/tau) - 1) frames at rest: 4.6 at 2, 3.2 at
    # 1.5, and a correction late against its motion reads less as the style. Held-out clips,
    # the default at hop 4: 2 -> 1.5 took the worst judge 89.2 -> 92.9 % exhausted (turning
    # walks most), jerk 1.008 -> 1.014, pops 1.21 -> 1.30, holds 1.49 -> 1.54 (the model card,
    # "A shorter correction low-pass"). The multi-style model keeps 2: at 1.5 its active
    # jerk went over the goal (1.09 -> 1.15).
    correction_tau = 1.5

    def __init__(self, model, rep: R.Representation, metadata: dict, direction: str = "a2b",
                 path: Path | None = None):
        if direction not in ("a2b", "b2a"):
            raise UserError(f"unknown direction {direction!r}; use a2b or b2a")
        from .networks import batch_invariant

        self.model = batch_invariant(model.eval())  # its words must not depend on their batch
        self.rep = rep
        self.metadata = metadata
        self.direction = direction
        self.path = path
        self.device = next(self.model.parameters()).device
        self._trep = None  # the representation in torch on self.device, built on first use

    # -- loading --------------------------------------------------------------------------
    @classmethod
    def load(cls, path_or_name=None, direction: str = "a2b", device: str = "cpu"):
        """Any kind of stylecast model (``MODEL_KINDS``, by the checkpoint's ``kind``; a
        pair CycleGAN when it names none). ``device``: "cpu", "cuda", "cuda:N" or "auto"
        (CUDA when present); a CUDA device asked for on a machine without one is refused
        in one sentence. ``direction`` applies to pair models only."""
        device = pick_device(device)
        path = ckpt.resolve(path_or_name)
        tensors, meta, rep = read_model(path)
        kind = meta.get("kind", PAIR_KIND)
        maker = MODEL_KINDS.get(kind) if isinstance(kind, str) else None
        if maker is None:
            raise UserError(f"checkpoint {path} is a model of kind {kind!r}, which this stylecast does not know "
                            f"({', '.join(MODEL_KINDS)}); use a matching stylecast")
        return maker.from_checkpoint(path, tensors, meta, rep, device, direction=direction)

    @classmethod
    def from_checkpoint(cls, path, tensors, meta, rep, device, direction: str = "a2b", **_) -> "Restyler":
        from .networks import CycleGAN, NetworkConfig

        styles = meta["styles"]
        if not (isinstance(styles, dict) and {"a", "b"} <= set(styles)):
            raise UserError(f"checkpoint {path} does not name its styles a and b; export it again with "
                            f"`stylecast train`")
        cfg = network_config(path, meta, NetworkConfig)
        model = build_checked(path, tensors, rep, cfg, lambda: CycleGAN(cfg, rep.combine), ("G_a2b.", "G_b2a."))
        model.to(device)
        return cls(model, rep, meta, direction, path)

    # -- facts ----------------------------------------------------------------------------
    @property
    def feet(self) -> str:
        """The foot lock ``--feet auto`` takes (motion.footlock.FEET): the one its checkpoint
        names (``train --feet``, measured in the model card), else its kind's default."""
        return self.metadata.get("feet") or self.default_feet

    def pace(self, weights=None) -> tuple:
        """The pace the stream covers ground at (``footlock.Pace``): the target style's
        against the source's (``pace.pace_points``). A pair has one target: ``weights`` is
        for the multi-style model's mixes."""
        from .pace import pace_points

        return pace_points(self.source_style, {self.target_style: 1.0})

    def amplitudes(self, weights=None) -> dict:
        """How far the stream's arms swing and hips rise and fall against the performer's
        (``footlock.GaitAmplitude``): a pair model's own, but for its runs' elbow bend. Its
        generator learned the swing and bob with its pair (the default towards exhausted
        swings a held-out walk's hands 17.2 cm against the input's 14.9, a run's 13.7 against
        16.1; real exhausted walks 16.4-20.8, runs 6.7-12.7), and the style's gains on top of
        that read less exhausted: 92.9 -> 87.3 % on the worst judge, FMD 13 -> 38x its floor
        (the model card, "Arm swing and hip bob"). Its runs' elbows it bends 85.7 degrees where
        real exhausted runs bend them 99-113; at the style's bend (``gait_amplitude.elbow_points``,
        the multistyle model's part) its runs read exhausted in 98.5 % of windows, not 89.7,
        and the worst judge 93.8 -> 95.2 % (the model card, "The elbows' bend in runs").
        ``weights`` as ``pace``'s."""
        from .gait_amplitude import elbow_points

        return {**NO_AMPLITUDES, "elbow_bend": elbow_points(self.source_style, {self.target_style: 1.0})}

    @property
    def styles(self) -> dict:
        return dict(self.metadata["styles"])

    @property
    def source_style(self) -> str:
        return self.styles["a" if self.direction == "a2b" else "b"]

    @property
    def target_style(self) -> str:
        return self.styles["b" if self.direction == "a2b" else "a"]

    @property
    def name(self) -> str:
        return self.path.stem if self.path else "model"

    @property
    def eval_source(self) -> str:
        """The style ``stylecast eval`` restyles from: the model's source."""
        return self.source_style

    def accepts_source(self, style: str) -> bool:
        """Whether this restyler is meant for input of ``style``."""
        return style == self.source_style

    def with_performer_style(self, style: str) -> "Restyler":
        """This restyler for input performed in ``style``: a pair model's source is its
        direction's, so it is itself for that style and refuses any other, and reads none."""
        if style == READ:
            raise UserError(f"model {self.name} cannot read the performer's style (--performer-style {READ}); "
                            f"load the multistyle model (--model multistyle) or name the style")
        if not self.accepts_source(style):
            raise UserError(f"model {self.name} restyles {self.source_style} input in this direction, not {style}; "
                            f"choose the direction instead, or load the multistyle model (--model multistyle)")
        return self

    @property
    def default_target(self) -> str | None:
        """The style ``stylecast eval`` measures when none is named."""
        return self.target_style

    def with_direction(self, direction: str) -> "Restyler":
        return Restyler(self.model, self.rep, self.metadata, direction, self.path)

    def for_target(self, style: str) -> "Restyler":
        """The direction that ends in ``style``; one sentence when the pair has no such one."""
        for direction in ("a2b", "b2a"):
            candidate = self.with_direction(direction)
            if candidate.target_style == style:
                return candidate
        raise UserError(f"model {self.name} restyles between {self.styles['a']} and {self.styles['b']} only, not "
                        f"towards {style!r}; choose one of those or the multistyle model")

    def with_style(self, text: str) -> "Restyler":
        """``--style``: a pair model can only go to one of its two styles, never a mix."""
        from .styles import STYLES, parse_mix

        weights = parse_mix(text)
        if np.count_nonzero(weights) != 1:
            raise UserError(f"model {self.name} cannot mix styles ({text!r}); use the multistyle model for a mix")
        return self.for_target(STYLES[int(np.argmax(weights))])

    # -- inference ------------------------------------------------------------------------
    def generator(self, direction: str | None = None):
        return self.model.G_a2b if (direction or self.direction) == "a2b" else self.model.G_b2a

    def restyle_features(self, features: np.ndarray, direction: str | None = None) -> np.ndarray:
        """Heading-free features (B, 60, J, C) -> restyled features, one batched pass."""
        import torch

        x = torch.from_numpy(np.ascontiguousarray(features, dtype=np.float32))
        return self._generate(x.to(self.device), direction).cpu().numpy()

    def to_device(self, array: np.ndarray):
        """A numpy array as a tensor on the model's device. On the CPU, shared with the
        array and without a torch operation: each operation releases the GIL and waits to
        win it back, which the daemon's model thread pays beside the output loop."""
        import torch

        t = torch.from_numpy(np.ascontiguousarray(array))
        return t if self.device.type == "cpu" else t.to(self.device)

    @staticmethod
    def to_host(tensor) -> np.ndarray:
        """A tensor as a numpy array, without a torch operation for one on the CPU."""
        return tensor.numpy() if tensor.device.type == "cpu" else tensor.cpu().numpy()

    def _network(self, batch: int, direction: str | None = None, *, words=None) -> tuple:
        """The generator module a batch of ``batch`` words goes through and the tensors
        that condition it (none for a pair model). ``words``: the batch's quaternion words,
        a tensor on the model's device, for a model that reads them to condition itself
        (none where the batch is given as features)."""
        return self.generator(direction), ()

    def _generate(self, features, direction: str | None):
        """Features (B, 60, J, C) float32 tensor on the model's device -> restyled features."""
        import torch

        from .networks import from_channels, to_channels

        network, conditioning = self._network(features.shape[0], direction)
        with torch.no_grad():  # one memory layout, one kernel: bit-equal paths
            y = network(to_channels(features.contiguous()), *conditioning)
        return from_channels(y, features.shape[2])

    @property
    def torch_representation(self):
        if self._trep is None:
            from .representation_torch import TorchRepresentation

            self._trep = TorchRepresentation(self.rep, self.device)
        return self._trep

    def restyle_words(self, words, direction: str | None = None):
        """Quaternion words (B, 60, 22, 4), humanoid local rotations xyzw -> same shape.
        Numpy in, numpy out (float64); a torch tensor in, a float64 tensor out on the
        model's device. One batched call on the device, nothing per word."""
        import torch

        from . import pipeline
        from . import representation_torch as RT

        is_tensor = isinstance(words, torch.Tensor)
        w = words.to(self.device, RT.DTYPE) if is_tensor else self.to_device(np.asarray(words, dtype=np.float64))
        _check_words_shape(tuple(w.shape))
        if len(w) == 0:
            out = w.clone()
        else:
            network, conditioning = self._network(len(w), direction, words=w)
            out = pipeline.restyle(network, self.torch_representation, w.contiguous(), conditioning)
        return out if is_tensor else self.to_host(out)

    def restyle_stream_words(self, words: np.ndarray, *args) -> tuple[np.ndarray, np.ndarray]:
        """The daemon's model-thread call (``daemon.inference``): words (B, 60, 22, 4) in
        any hemisphere -> (the restyled words, each continuous in time, float64; (B,) bool,
        each word usable), in one traced call (``pipeline.StreamWordPipeline``); the same
        bits as ``restyle_words`` on the words made continuous in time, then made
        continuous. ``args`` as ``restyle_words``'s."""
        from . import pipeline

        w = self.to_device(np.asarray(words, dtype=np.float64))
        _check_words_shape(tuple(w.shape))
        network, conditioning = self._network(len(w), *args, words=w)
        out, ok = pipeline.restyle_for_stream(network, self.torch_representation, w, conditioning)
        return self.to_host(out), self.to_host(ok)

    def warm_up(self) -> None:
        """Each generator this model can run live (both directions) called once on one
        identity word as the daemon calls it, off the clock. A generator's first call
        traces its graph (``pipeline``): 130-160 ms alone here, 250 ms inside a loaded
        daemon, where a model swapped in live once paid it on the clock (its first words
        late, and the planner raised the delay to 23 frames for the minutes it took to
        come back down); a direction changed live paid it too."""
        for direction in ("a2b", "b2a"):
            self.restyle_stream_words(_identity_words(), direction)

    def restyle_words_eager(self, words: np.ndarray, *args) -> np.ndarray:
        """``restyle_words`` on numpy words with its operations run one by one instead of as
        the traced graph (``pipeline.restyle_eager``); ``args`` as ``restyle_words``'s."""
        import torch

        from . import pipeline

        w = torch.from_numpy(np.asarray(words, dtype=np.float64)).to(self.device)
        network, conditioning = self._network(len(words), *args, words=w)
        return pipeline.restyle_eager(network, self.torch_representation, w, conditioning).cpu().numpy()

    def restyle_words_numpy(self, words: np.ndarray, direction: str | None = None) -> np.ndarray:
        """The numpy reference of ``restyle_words`` (representation work on the host, per
        ``representation``); kept for the tests that prove the torch path equal to it."""
        words = np.asarray(words, dtype=np.float64)
        _check_words_shape(words.shape)
        if len(words) == 0:
            return words.copy()
        flat, yaw = R.remove_heading(words)
        out = self.rep.decode(self.restyle_features(self.rep.encode(flat), direction))
        out = R.restore_heading(out, yaw)
        # Same hemisphere as the input, frame by frame: q and -q are one rotation, and the
        # blender interpolates between input and output.
        sign = np.where(np.sum(out * words, axis=-1, keepdims=True) < 0, -1.0, 1.0)
        return out * sign

    __call__ = restyle_words


PAIR_KIND = "cyclegan"
# Model kinds by the checkpoint's "kind": the one place a kind is known (each registers
# itself with ``register_kind``; ``stylecast.models`` imports every kind's module).
MODEL_KINDS: dict[str, type] = {PAIR_KIND: Restyler}


def register_kind(name: str):
    def register(cls):
        MODEL_KINDS[name] = cls
        return cls
    return register


def read_model(path: Path):
    """(tensors, metadata, representation) of a checkpoint, everything but the network
    checked: integrity, bones, word length, fps, retarget version, representation."""
    tensors, meta = ckpt.read_checkpoint(path)
    ckpt.validate_metadata(path, meta, HUMANOID_BONES, WORD_LENGTH, FPS)
    version = meta.get("retarget_version", 1)
    if version != RETARGET_VERSION:
        raise UserError(f"checkpoint {path} was trained on humanoid rotations of retarget version {version}, "
                        f"this stylecast maps motion with version {RETARGET_VERSION}; retrain the model "
                        f"(`stylecast train`)")
    if meta.get("feet") is not None and meta["feet"] not in FEET:
        raise UserError(f"checkpoint {path} names the foot lock {meta['feet']!r}, which this stylecast does not "
                        f"know ({', '.join(FEET)}); use a matching stylecast or export it again")
    rep_meta = meta["representation"]
    name = rep_meta.get("name") if isinstance(rep_meta, dict) else None
    if name not in R.REPRESENTATIONS:
        raise UserError(f"checkpoint {path} uses the representation {name!r}, which this stylecast does not "
                        f"know ({', '.join(R.REPRESENTATIONS)}); use a matching stylecast")
    reference = rep_meta.get("reference")
    if reference is not None:
        try:
            reference = np.asarray(reference, dtype=np.float64)
        except (TypeError, ValueError):
            reference = np.zeros(0)  # refused just below
        if reference.shape != (len(HUMANOID_BONES), 4) or not np.allclose(np.linalg.norm(reference, axis=1), 1,
                                                                            atol=1e-6):
            raise UserError(f"checkpoint {path} has a malformed reference pose (want {len(HUMANOID_BONES)} unit "
                            f"quaternions); export it again with `stylecast train`")
    rep = R.get_representation(name, reference)
    if name == "euler" and (rep_meta.get("euler_order") != R.EULER_ORDER or
                            rep_meta.get("normalisation") != rep.metadata()["normalisation"]):
        raise UserError(f"checkpoint {path} uses Euler order {rep_meta.get('euler_order')} with normalisation "
                        f"{rep_meta.get('normalisation')}, this stylecast uses {R.EULER_ORDER} scaled by "
                        f"1/{R.EULER_SCALE_DEG:g} after centring; retrain the model")
    return tensors, meta, rep


def network_config(path, meta: dict, config_cls):
    """The checkpoint's network settings as ``config_cls``, every value type- and size-checked."""
    settings = meta["network"]
    if isinstance(settings, dict) and "correction_knots" not in settings:
        # Checkpoints from before the smooth correction existed: a free full-rate one.
        settings = {**settings, "correction_knots": 0}
    fields = config_cls.__dataclass_fields__
    if not isinstance(settings, dict) or set(settings) - set(fields):
        raise UserError(f"checkpoint {path} has network settings this stylecast does not understand; use a "
                        f"matching stylecast or retrain")
    for key, value in settings.items():
        kind = fields[key].type
        smallest = 0 if key in config_cls.MAY_BE_ZERO else 1
        ok = (isinstance(value, int) and not isinstance(value, bool) and smallest <= value <= MAX_NETWORK_SIZE) \
            if kind in (int, "int") \
            else (isinstance(value, (int, float)) and not isinstance(value, bool) and np.isfinite(value))
        if not ok:
            raise UserError(f"checkpoint {path} has a malformed network setting {key}={value!r}; export it "
                            f"again with `stylecast train`")
    try:
        return config_cls(**settings)
    except ValueError as exc:
        raise UserError(f"checkpoint {path} has impossible network settings ({ckpt.short_reason(exc)}); export "
                        f"it again with `stylecast train`") from None


def build_checked(path, tensors, rep, cfg, make, prefixes: tuple[str, ...]):
    """The network ``make()`` with the checkpoint's weights under ``prefixes``, after checking
    sizes and shapes on an outline built on torch's "meta" device, which allocates nothing:
    settings claiming a huge network are refused before any memory is used."""
    import torch

    if cfg.channels != rep.channels or cfg.joints != len(HUMANOID_BONES):
        raise UserError(f"checkpoint {path} declares {cfg.joints} bones x {cfg.channels} channels, but its "
                        f"representation needs {len(HUMANOID_BONES)} x {rep.channels}; export it again")
    try:
        with torch.device("meta"):
            outline = make()
    except (RuntimeError, ValueError) as exc:  # sizes no network could have
        raise UserError(f"checkpoint {path} describes an impossible network ({ckpt.short_reason(exc)}); "
                        f"export it again with `stylecast train`") from None
    state = ckpt.check_shapes(path, outline, tensors, prefixes)
    model = make()
    model.load_state_dict(state, strict=False)  # discriminators are optional in a checkpoint
    return model


def _identity_words(batch: int = 1) -> np.ndarray:
    """``batch`` words of the rest pose (every rotation the identity)."""
    words = np.zeros((batch, WORD_LENGTH, len(HUMANOID_BONES), 4))
    words[..., 3] = 1.0
    return words


def _check_words_shape(shape: tuple) -> None:
    if len(shape) != 4 or shape[1:] != (WORD_LENGTH, len(HUMANOID_BONES), 4):
        raise ValueError(f"words must have shape (B, {WORD_LENGTH}, {len(HUMANOID_BONES)}, 4), got {shape}")
