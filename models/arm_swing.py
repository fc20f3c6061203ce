"""How far each style swings its arms while it walks and runs: the gain ``footlock.ArmSwing``
gives a restyled stream's arms.

The generator restyles each word's poses but barely changes how far the arms swing (the
multistyle model towards elderly: the hands' swing 13.1 cm, the input's 13.8, real elderly
walks' 7.1), and the swing reads as style: its held-out elderly walks read elderly in 11-35 %
of windows on the judges, 72-91 % with the input's swing scaled to the elderly takes'
(a diagnostic, MODEL_CARD.md "Arm swing"). So the stream scales the performer's swing by
the target style's over the source's, at the source's walking and running paces.

``ARM_SWINGS`` is measured on the training split only (the held-out files stay unseen), with
``measure_arm_swings``; ``tests/test_arm_swing.py`` checks the table against the data.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from stylecast.motion.clock import OUTPUT_FPS

from .pace import PACES, per_style_locomotion

# The hands' forward swing against the hips (cm, ``metrics.arm_swing``: the standard
# deviation about its running mean, both hands averaged) of each style's training clips:
# (walks, runs), the walking actions' means averaged.
ARM_SWINGS = {
    "active": (16.25, 27.49),
    "elderly": (7.09, 14.64),
    "exhausted": (16.72, 9.13),
    "feminine": (13.26, 21.13),
    "masculine": (13.90, 21.60),
    "normal": (13.84, 14.63),
    "youthful": (21.33, 26.36),
}


def arm_swing_points(source: str, target: Mapping[str, float]) -> tuple[tuple[float, float], ...]:
    """``ContactSettings.arm_swing`` for input of style ``source`` restyled towards the mix
    ``target`` (style -> weight, summing to 1): (input speed in cm a frame at the stream's
    rate, gain), one point at the source's walking pace and one at its running pace; ()
    where a style's swing is not known (the input's swing is kept)."""
    mix = {style: weight for style, weight in target.items() if weight > 0}
    if source not in ARM_SWINGS or not mix or any(style not in ARM_SWINGS for style in mix):
        return ()
    out = sum(weight * np.asarray(ARM_SWINGS[style]) for style, weight in mix.items()) / sum(mix.values())
    return tuple((float(speed) / OUTPUT_FPS, float(b) / float(a))
                 for speed, a, b in zip(PACES[source], ARM_SWINGS[source], out))


def measure_arm_swings(files, cache_dir=None) -> dict[str, tuple[float, float]]:
    """``ARM_SWINGS`` from the dataset's training split: {style: (walks, runs)} in cm."""
    from . import data as D
    from .metrics import arm_swing, hips_yaw, world_positions

    skeleton = D.bandai_skeleton(files)
    return per_style_locomotion(
        files, lambda m: arm_swing(hips_yaw(m.rotations), world_positions(m.rotations, m.root_positions, skeleton)),
        cache_dir)
