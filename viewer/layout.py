"""Where and in which colour each performer is drawn (pure: no GL, no sockets).

``side``: each slot's input skeleton stands at -X and its restyled skeleton at +X of the
slot's place (from the front, the camera's default view, that reads "before | after").
``overlay``: both stand on the same spot; the input is drawn as a translucent shell over
the opaque restyled skeleton, so identical poses show one figure and differences show two.
Slots are spread along X by ``spacing`` so several performers who all start at the origin
(replays usually do) do not stand inside each other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LAYOUTS = ("side", "overlay")
COLOURS = {"restyled": (1.0, 0.55, 0.18), "input": (0.35, 0.62, 1.0)}
STALE_COLOUR = (0.5, 0.5, 0.5)
STALE_AFTER_S = 1.0  # a performer silent this long is drawn grey: its pose is old
OVERLAY_ALPHA = 0.4
DEFAULT_SPACING = 1.8  # metres between neighbours: T-pose arms (about 1.6 m) never touch


@dataclass(frozen=True)
class Placement:
    offset: np.ndarray  # (3,) metres added to every joint
    colour: tuple[float, float, float, float]
    translucent: bool


def place(performers, layout: str, spacing: float, now: float) -> list[Placement]:
    """One placement per performer (any objects with ``role``, ``slot``, ``last_seen``)."""
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    paired = layout == "side" and {p.role for p in performers} >= {"input", "restyled"}
    slot_width = spacing * (2 if paired else 1)
    slots = sorted({p.slot for p in performers})
    centre = (slots[0] + slots[-1]) / 2 if slots else 0.0
    out = []
    for p in performers:
        x = (p.slot - centre) * slot_width
        if paired:
            x += -spacing / 2 if p.role == "input" else spacing / 2
        rgb = COLOURS.get(p.role, COLOURS["restyled"])
        if now - p.last_seen > STALE_AFTER_S:
            rgb = STALE_COLOUR
        translucent = layout == "overlay" and p.role == "input"
        out.append(Placement(np.array([x, 0.0, 0.0]), (*rgb, OVERLAY_ALPHA if translucent else 1.0), translucent))
    return out
