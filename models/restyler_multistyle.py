"""``MultiStyleRestyler``: the multi-style model (``multistyle.py``) as a batch function.

    r = Restyler.load("multistyle")               # kind "multistyle": this class
    r = r.with_style("elderly:0.5,youthful:0.5")  # or r.for_target("elderly"), r.with_mix(w)
    out = r.restyle_words(words)                  # every word towards the restyler's mix
    out = r.restyle_words(words, weights)         # (B, 7): one mix per word, one call

The input may be in any style: the generator is told only the target. The share of a mix
that is the performer's own style (``performer_style``, default the neutral style, as the
pace assumes) means "as performed": it scales the correction down instead of entering the
code, so the performer's own style is the input itself and a half mix with it is half the
restyle (``code_and_intensity``); with ``performer_style`` ``auto`` (``styles.READ``) the
checkpoint's style reader reads that style from each word (``style_reader``). Everything
around the generator (heading, representation, hemisphere, one batched call under no_grad)
is the pair restyler's (``restyler.Restyler``).
"""

from __future__ import annotations

import copy

import numpy as np

from stylecast.motion.errors import UserError
from stylecast.motion.smoothing import CORRECTION_TAU

from .restyler import Restyler, _identity_words, build_checked, network_config, register_kind
from .styles import NEUTRAL, READ, STYLES, check_performer_style, describe_mix, one_hot, parse_mix

KIND = "multistyle"


@register_kind(KIND)
class MultiStyleRestyler(Restyler):
    direction = ""  # no directions: a style (mix) instead
    default_feet = "stance"  # its stances (masculine, feminine, youthful) need it: see the model card
    # ...but a mix led by one of these styles plants on the input's ankles: with the style's
    # pace, on the worst judge, elderly 68.8 -> 78.2 % (action kept 69.1 -> 76.5 %) and
    # exhausted 69.1 -> 77.1 % (88.7 -> 89.5 %), where feminine fell 78 -> 2 % and masculine
    # 69 -> 24 % (the model card, "The style's pace"); and swings its feet on the input's
    # path (``ContactSettings.swing_path``): elderly 56.4 -> 61.5 %, exhausted 92.9 -> 95.5 %
    # on the worst judge, their swings dipping in 3 and 7 % rather than 100 and 96 % (the
    # model card, "Swings on the input's path"). Read when a lock is built: a session keeps
    # its lock when its style changes live.
    feet_of_style = {"elderly": "path", "exhausted": "path"}
    # The share of the hips' low-pass a style asks to follow the restyled legs within 2
    # frames rather than the stance's 8 (``ContactSettings.pelvis_quick_tau``), weighted by
    # the mix. Masculine, whose walks bend step by step: all of it (66.6 -> 86.1 % on the
    # worst judge; the stance at 2 for every style read feminine 86.4 -> 55.2 %). Active:
    # half, since all of it put its jerk over the bar (1.093 -> 1.106; half: 1.095, and
    # 60.6 -> 68.8 % on the worst judge). The model card, "The hips a style asks for".
    quick_hips_of_style = {"masculine": 1.0, "active": 0.5}
    # The share of the stance's place a style keeps while the performer stands
    # (``ContactSettings.stance_standing``; walking, all of it), weighted by the mix; the
    # others keep all of it. Active: none, since its restyled standing stance is wider than
    # any real active take's (raises and waves 17.7-21.6 cm, real 14.4-17.3) and the
    # performer's own (14.3-15.2) lies inside: its raises read active 51-85 -> 81-90 % on the
    # judges' mean, its style 91.5 -> 94.4 and 85.4 -> 91.0 % on the two panels' (worst judge
    # 90.1 -> 89.2 and 75.9 -> 80.5 %; 0.4 of it read less on both: the model card, "Active
    # stands as the performer stands"). Masculine, feminine and youthful stand inside their
    # real ranges with their stance and far outside without it.
    standing_stance_of_style = {"active": 0.0}
    # Its first words, mostly the stream's first pose held, disagree more than the pair
    # model's: shown at once (not faded in), arms and feet popped in the first 16 frames of
    # held-out takes (the worst clip's largest one-frame jerk up to 74x the input's, against
    # 1.7-3.9x faded in; the model card, "A stream's first frame, restyled").
    start_restyled = False
    correction_tau = CORRECTION_TAU  # the pair model's shorter one put active's jerk over its goal

    def __init__(self, model, rep, metadata: dict, weights=None, path=None, intensity: float = 1.0, reader=None):
        from .networks import batch_invariant

        self.model = batch_invariant(model.eval())  # its words must not depend on their batch
        self.rep = rep
        self.metadata = metadata
        self.path = path
        self.device = next(self.model.parameters()).device
        self._trep = None
        self.style_names = tuple(metadata["styles"])
        self.weights = one_hot(NEUTRAL, self.style_names) if weights is None else np.asarray(weights, np.float64)
        self.intensity = float(intensity)
        self.performer_style = NEUTRAL  # the style the input is taken to be in: ``with_performer_style``
        self.reader = reader  # the checkpoint's ``style_reader.StyleReader``, if it has one

    @property
    def feet(self) -> str:
        """``--feet auto``: the lock the checkpoint names, else that of the style leading the
        mix (``feet_of_style``), else the stance."""
        named = self.metadata.get("feet")
        if named:
            return named
        lead = self.style_names[int(np.argmax(self.weights))]
        return self.feet_of_style.get(lead, self.default_feet)

    def pace(self, weights=None) -> tuple:
        """The pace of the mix ``weights`` (default this restyler's) against the performer's
        style's (``performer_style``: the neutral style unless told, since the training clips
        of the other styles are restyled from normal; ``pace.pace_points``). A style read word
        by word (``auto``) gives no pace: the input's is kept, as for an unknown style."""
        from .pace import pace_points

        return pace_points(self.performer_style, self._mix_of(weights))

    def amplitudes(self, weights=None) -> dict:
        """The arm swing and hip bob of the mix ``weights`` against the performer's style's,
        as ``pace`` (``gait_amplitude.amplitudes``)."""
        from .gait_amplitude import amplitudes

        return amplitudes(self.performer_style, self._mix_of(weights))

    def quick_hips(self, weights=None) -> float:
        """The share of the hips' low-pass at the quick time constant for the mix ``weights``
        (default this restyler's): each style's ``quick_hips_of_style`` by its weight."""
        return float(sum(self.quick_hips_of_style.get(name, 0.0) * w for name, w in self._mix_of(weights).items()))

    def standing_stance(self, weights=None) -> float:
        """The share of the stance's place kept standing for the mix ``weights`` (default
        this restyler's): each style's ``standing_stance_of_style`` (else 1) by its weight."""
        return float(sum(self.standing_stance_of_style.get(name, 1.0) * w for name, w in self._mix_of(weights).items()))

    def _mix_of(self, weights=None) -> dict:
        """{style: weight} of the mix ``weights`` (default this restyler's)."""
        mix = self.weights if weights is None else np.asarray(weights, np.float64)
        return dict(zip(self.style_names, mix.tolist()))

    @classmethod
    def from_checkpoint(cls, path, tensors, meta, rep, device, **_) -> "MultiStyleRestyler":
        from .multistyle import MultiStyleConfig, make_generator
        from .representation_torch import TorchRepresentation
        from .style_reader import StyleReader

        styles = meta["styles"]
        if not (isinstance(styles, list) and tuple(styles) == STYLES):
            raise UserError(f"checkpoint {path} names the styles {styles!r}, this stylecast's multi-style models "
                            f"have {', '.join(STYLES)}; export it again with `stylecast train --styles all`")
        cfg = network_config(path, meta, MultiStyleConfig)
        if cfg.num_styles != len(STYLES):
            raise UserError(f"checkpoint {path} has {cfg.num_styles} style codes for {len(STYLES)} styles; export "
                            f"it again with `stylecast train --styles all`")
        model = build_checked(path, {k[2:]: v for k, v in tensors.items() if k.startswith("G.")}, rep, cfg,
                              lambda: make_generator(cfg, rep.combine), ("",))
        model.to(device)
        reader = StyleReader.from_checkpoint(path, tensors, meta, TorchRepresentation(rep, device))
        return cls(model, rep, meta, path=path, reader=reader)

    # -- facts ----------------------------------------------------------------------------
    @property
    def styles(self) -> list[str]:
        return list(self.style_names)

    @property
    def source_style(self) -> str:
        """The style the input is taken to be in (``with_performer_style``): any style is
        accepted, and this one is what the status line and ``restyle`` name as the source."""
        return self.performer_style

    @property
    def eval_source(self) -> str:
        return NEUTRAL  # the bar is read from normal input

    def accepts_source(self, style: str) -> bool:
        return True  # only the target is given to the generator: any input style

    @property
    def default_target(self) -> None:
        return None  # any style: ``stylecast eval`` needs --target

    @property
    def target_style(self) -> str:
        return describe_mix(self.weights, self.style_names)

    def style_codes(self) -> np.ndarray:
        """The code table (S, code_dim)."""
        return self.model.codes.table.detach().cpu().numpy()

    # -- choosing the style -----------------------------------------------------------------
    def with_mix(self, weights, intensity: float | None = None) -> "MultiStyleRestyler":
        """The same model (shared, not copied) with another mix."""
        w = np.asarray(weights, np.float64)
        if w.shape != (len(self.style_names),) or not (np.all(np.isfinite(w)) and np.all(w >= 0) and w.sum() > 0):
            raise UserError(f"a style mix needs {len(self.style_names)} finite weights >= 0 with a positive sum, "
                            f"got {w.tolist()}")
        other = copy.copy(self)
        other.weights = w / w.sum()
        other.intensity = self.intensity if intensity is None else float(intensity)
        return other

    def with_performer_style(self, style: str) -> "MultiStyleRestyler":
        """The same model for input performed in ``style``: its share of a mix is the input
        as performed (``code_and_intensity``), and the pace starts from its pace. ``auto``
        (``READ``): the style read from each word by the checkpoint's reader."""
        check_performer_style(style, self.style_names)
        if style == READ and self.reader is None:
            raise UserError(f"model {self.name} has no style reader to read the performer's style with; add one "
                            f"with `stylecast train-reader --model {self.path or self.name}`, or name the style")
        other = copy.copy(self)
        other.performer_style = style
        return other

    def with_style(self, text: str) -> "MultiStyleRestyler":
        return self.with_mix(parse_mix(text, self.style_names))

    def for_target(self, style: str) -> "MultiStyleRestyler":
        return self.with_mix(one_hot(style, self.style_names))

    def warm_up(self) -> None:
        """``Restyler.warm_up``: its one generator."""
        self.restyle_stream_words(_identity_words())

    def with_direction(self, direction: str):
        raise UserError(f"model {self.name} has no directions; choose its style instead (--style NAME, "
                        f"/stylecast/style NAME)")

    # -- inference ------------------------------------------------------------------------
    def generator(self, direction=None):
        """The generator conditioned on this restyler's mix: a module of x (B, F, T) alone,
        as the pair's ``generator()`` (benchmarks time it)."""
        from torch import nn

        model, weights = self.model, self.weights

        class Conditioned(nn.Module):
            def __init__(self):
                super().__init__()
                self.net = model

            def forward(self, x):
                w = x.new_tensor(weights).expand(x.shape[0], -1)
                return self.net(x, w)

        return Conditioned()

    def restyle_words(self, words, weights=None):
        """Words (B, 60, 22, 4) -> restyled, one batched call; ``weights`` (B, S) gives each
        word its own mix (default: the restyler's mix for all)."""
        return super().restyle_words(words, weights)

    __call__ = restyle_words

    def _network(self, batch: int, weights=None, *, words=None) -> tuple:
        """The conditioned generator and its conditioning: each word's mix (``weights``
        (B, S), default this restyler's) and the intensity. Worked out in numpy and handed
        over without a torch operation (``to_device``): the daemon's model thread runs this
        beside the output loop, and each eager torch operation (a dozen here) released the
        GIL and waited to win it back. Beside a thread busy in Python (1 ms switch
        interval) a job of 8 words took 14.6 ms with them in torch, against 9.7 ms
        worked out before the call (Intel Xeon VM, 2 vCPUs; scratch measure, 2026-11-29).
        A style read from the ``words`` (``auto``) adds one traced call (``pipeline.read_styles``)."""
        if weights is None:
            w = np.broadcast_to(np.asarray(self.weights, np.float32), (batch, len(self.style_names)))
        else:
            if hasattr(weights, "detach"):  # a tensor, on any device
                weights = weights.detach().cpu().numpy()
            w = np.asarray(weights, np.float32)
            if w.shape != (batch, len(self.style_names)):
                raise ValueError(f"style weights must have shape ({batch}, {len(self.style_names)}), got {w.shape}")
        code, kept = code_and_intensity(w, self._performer(batch, words))
        kept = (np.float32(self.intensity) * kept).astype(np.float32)
        return self.model, (self.to_device(code), self.to_device(kept))

    def _performer(self, batch: int, words) -> np.ndarray:
        """The performer's style of each word (B, S): read from the ``words`` (``auto``),
        else the named style's one-hot row."""
        if self.performer_style != READ:
            return np.broadcast_to(one_hot(self.performer_style, self.style_names).astype(np.float32),
                                   (batch, len(self.style_names)))
        if words is None:
            raise ValueError("the performer's style is read from the words; this path gave the model features")
        return self.reader.read(words)


def code_and_intensity(weights: np.ndarray, performer: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mixes ``weights`` (B, S), one per word, and the performer's style of each word,
    ``performer`` (B, S) (a named style's one-hot row, or a reader's probabilities) -> (the
    generator's code weights (B, S), the share of the correction kept (B,)), float32. The
    mix's overlap with the performer's style (per style the smaller of the two) is the
    input as performed: it is left out of the code and scales the correction down, so the
    performer's own style is exactly the input and "elderly 0.5" (half the neutral style's)
    is half of elderly's correction. The generator is told only a target, and the code of
    the input's own style does not restyle it to itself: held-out normal words told
    "normal" moved 3.55 degrees a bone on average (9.8 on the worst bone), against 9.0 for
    "exhausted" (scratch measure, 2026-11-27). A mix that is all the performer's keeps its
    code (any: its correction is scaled to nothing), so the weights stay continuous through
    a crossfade to or from the performer's own style; and a reading is continuous too: a
    word read 60 % elderly keeps 40 % of an elderly target's correction."""
    weights = np.asarray(weights, np.float32)
    total = weights.sum(axis=1)
    # A one-hot row gives exactly the mix without its performer's share (w - w = 0, w - 0 = w).
    others = weights - np.minimum(weights, np.asarray(performer, np.float32) * total[:, None])
    rest = others.sum(axis=1)
    code = np.where((rest > 0)[:, None], others / np.maximum(rest, np.float32(1e-12))[:, None], weights)
    return np.ascontiguousarray(code, np.float32), (rest / total).astype(np.float32)
