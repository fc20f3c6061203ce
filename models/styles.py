"""The style space of the multi-style model: the style names and style mixes.

``STYLES`` is the one list of the Bandai dataset-2 styles (alphabetical, the order of
``data.styles_present`` and of the judges), and the row order of a multi-style model's
code table. A *mix* is a weight per style, (7,) non-negative and summing to 1; a model
turns it into a code as the weighted sum of its style codes (``multistyle.StyleCodes``).

    parse_mix("elderly")                      -> one-hot elderly
    parse_mix("elderly:0.5,youthful:0.5")     -> half and half
    describe_mix(w)                           -> "elderly 0.50 + youthful 0.50"
"""

from __future__ import annotations

import math

import numpy as np

from stylecast.motion.errors import UserError

STYLES = ("active", "elderly", "exhausted", "feminine", "masculine", "normal", "youthful")
NEUTRAL = "normal"  # the dataset's neutral style: a multi-style model's default, a weight's remainder
READ = "auto"  # ``--performer-style auto``: the performer's style read from their words (``style_reader``)


def check_style(name: str, known=STYLES) -> int:
    """The index of a style name, or one sentence naming the known ones."""
    if name not in known:
        raise UserError(f"unknown style {name!r}; the known styles are {', '.join(known)}")
    return list(known).index(name)


def check_performer_style(name: str, known=STYLES) -> None:
    """A performer's style: a style name or ``READ``, else one sentence naming them."""
    if name != READ and name not in known:
        raise UserError(f"unknown performer style {name!r}; name one of {', '.join(known)}, or {READ} to have "
                        f"it read from the performer's motion")


def mix_from_pairs(pairs, known=STYLES) -> np.ndarray:
    """[(name, weight), ...] -> normalised (len(known),) weights. Weights must be finite and
    >= 0 with a positive sum; a name given twice adds up."""
    w = np.zeros(len(known))
    for name, weight in pairs:
        k = check_style(name, known)
        if not (isinstance(weight, (int, float)) and math.isfinite(weight) and weight >= 0):
            raise UserError(f"the weight of style {name!r} must be a finite number >= 0, got {weight!r}")
        w[k] += float(weight)
    if not w.sum() > 0:
        raise UserError("a style mix needs at least one positive weight, e.g. elderly:0.5,youthful:0.5")
    return w / w.sum()


def parse_mix(text: str, known=STYLES) -> np.ndarray:
    """"NAME" or "NAME:W,NAME:W,..." -> normalised weights (the --style option)."""
    pairs = []
    for part in (p.strip() for p in str(text).split(",")):
        if not part:
            continue
        name, sep, weight = part.partition(":")
        if not sep:
            pairs.append((name.strip(), 1.0))
            continue
        try:
            value = float(weight)
        except ValueError:
            raise UserError(f"style weight {weight!r} of {name.strip()!r} is not a number; write e.g. "
                            f"elderly:0.5,youthful:0.5") from None
        pairs.append((name.strip(), value))
    if not pairs:
        raise UserError(f"no style given; name one of {', '.join(known)} (or a mix like elderly:0.5,youthful:0.5)")
    return mix_from_pairs(pairs, known)


def one_hot(name: str, known=STYLES) -> np.ndarray:
    w = np.zeros(len(known))
    w[check_style(name, known)] = 1.0
    return w


def describe_mix(weights, known=STYLES) -> str:
    """"elderly" for a one-hot mix, else "elderly 0.50 + youthful 0.50" (largest first)."""
    w = np.asarray(weights, dtype=np.float64)
    order = [k for k in np.argsort(-w, kind="stable") if w[k] > 1e-6]
    if len(order) == 1:
        return known[order[0]]
    return " + ".join(f"{known[k]} {w[k]:.2f}" for k in order)
