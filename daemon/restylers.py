"""Where the daemon gets a restyler, and two stand-ins.

The daemon accepts any object with ``restyle_words(words (B, 60, J, 4)) -> same shape``.
``load_restyler`` resolves a name: "identity" and "standin" are built in (for tests,
benches and machines without a trained checkpoint); anything else is handed to
``stylecast.models``' ``Restyler.load`` (a shipped model name or a checkpoint path).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from stylecast.motion.errors import UserError


class IdentityRestyler:
    """Returns every word unchanged: the daemon's machinery without a model."""

    name = "identity"
    direction = ""

    def restyle_words(self, words: np.ndarray) -> np.ndarray:
        return np.array(words, dtype=np.float64, copy=True)


class StandInRestyler:
    """Deterministic and deliberately *word-dependent*: each bone is turned by a fraction
    of that bone's mean rotation over the word (so two overlapping words disagree where
    they meet, as a real model's do, and the seam blender has real work), plus a fixed
    lean. Words are independent of each other, so batching does not change the result."""

    name = "standin"
    direction = ""

    def __init__(self, gain: float = 0.3, lean_deg: float = 8.0):
        self.gain = gain
        self.lean = Rotation.from_euler("X", lean_deg, degrees=True)

    def restyle_words(self, words: np.ndarray) -> np.ndarray:
        w = np.asarray(words, dtype=np.float64)
        B, T, J, _ = w.shape
        mean = w.mean(axis=1)  # (B, J, 4): a crude but smooth word-level statistic
        mean /= np.linalg.norm(mean, axis=-1, keepdims=True)
        extra = Rotation.from_rotvec(Rotation.from_quat(mean.reshape(-1, 4)).as_rotvec() * self.gain)
        extra = self.lean * extra
        per_frame = Rotation.from_quat(np.repeat(extra.as_quat().reshape(B, 1, J, 4), T, axis=1).reshape(-1, 4))
        return (per_frame * Rotation.from_quat(w.reshape(-1, 4))).as_quat().reshape(B, T, J, 4)


def load_restyler(name: str, device: str = "cpu"):
    """``device``: where a trained model runs (auto, cpu, cuda[:N]); stand-ins are numpy."""
    if name in ("identity", "none"):
        return IdentityRestyler()
    if name == "standin":
        return StandInRestyler()
    try:
        import stylecast.models as models

        restyler_cls = getattr(models, "Restyler", None)
        if restyler_cls is None:
            from stylecast.models.restyler import Restyler as restyler_cls  # noqa: N813
    except ImportError:
        raise UserError(f"model {name!r} cannot be loaded: stylecast.models has no Restyler in this "
                        f"install; use --model identity to run without restyling") from None
    return restyler_cls.load(name, device=device)


def warm_up(restyler) -> None:
    """Whatever a model needs run once before it goes live (``Restyler.warm_up``: each of
    its generators' graphs traced); stand-ins need nothing."""
    warm = getattr(restyler, "warm_up", None)
    if callable(warm):
        warm()


def model_name(restyler) -> str:
    return str(getattr(restyler, "name", None) or type(restyler).__name__)


def style_label(restyler) -> str:
    """What the status shows: "normal->exhausted" for a real model, else its name."""
    try:
        return f"{restyler.source_style}->{restyler.target_style}"
    except Exception:  # stand-ins and models without style metadata
        return model_name(restyler)


def with_direction(restyler, direction: str):
    """A restyler for another direction (e.g. "a2b"/"b2a"); refused with one sentence."""
    maker = getattr(restyler, "with_direction", None)
    if callable(maker):
        return maker(direction)  # the model's own check refuses unknown directions
    raise UserError(f"model {model_name(restyler)} has no directions to choose from; load a trained model")


def with_style(restyler, text: str):
    """``serve --style NAME`` or a mix "NAME:W,NAME:W": the model's own style from then on
    (a pair model takes one of its two styles); refused with one sentence."""
    maker = getattr(restyler, "with_style", None)
    if callable(maker):
        return maker(text)  # the model's own check names its styles
    raise UserError(f"model {model_name(restyler)} has no styles to choose from; load the multistyle model "
                    f"(--model multistyle)")


def with_performer_style(restyler, style: str):
    """``serve --performer-style NAME``: the model told the style the performers move in
    (a pair model refuses another than its source); stand-ins and "" pass unchanged."""
    maker = getattr(restyler, "with_performer_style", None)
    return maker(style) if style and callable(maker) else restyler


def style_mix(restyler, pairs) -> tuple:
    """(weights, label) of a live style change for ``restyler``'s style codes."""
    if not callable(getattr(restyler, "with_mix", None)):
        raise UserError(f"model {model_name(restyler)} has no style codes to mix; load the multistyle model "
                        f"(/stylecast/model multistyle)")
    from stylecast.models.styles import describe_mix, mix_from_pairs

    weights = mix_from_pairs(pairs, restyler.styles)
    return weights, describe_mix(weights, restyler.styles)
