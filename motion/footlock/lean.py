"""The upper body's lean across (``GaitAmplitude``'s lean part, ``performer_lean``): how far
the line from the spine's joint to the head tilts towards the humanoid's left, and the turn
of the spine that tilts it further.

The multistyle generator leans its walks' upper bodies to the right: the head 2.0-2.5 cm to
the right of the hips towards active and youthful where the performer's held-out walks lean
0.1 cm and real walks of every style within 0.8 on average, and its left-turning walks lean
right too where a real turn leans into it (the model card, "Walks lean into a turn"). The
lean is read from the spine's joint, the point the correction turns about, so that a turn by
an angle tilts it by exactly that angle (read from the hips it moved two thirds as far: the
hips-to-spine bone does not turn).
"""

from __future__ import annotations

import numpy as np

from .. import rotations as rot
from ..humanoid import HUMANOID_BONES, UP
from .across import left_of_hips

HIPS_INDEX = HUMANOID_BONES.index("Hips")
SPINE_INDEX = HUMANOID_BONES.index("Spine")
# From the spine's joint up to the head: each bone's offset is turned by its parents' rotations.
_UP_THE_SPINE = [HUMANOID_BONES.index(name) for name in ("Chest", "UpperChest", "Neck", "Head")]


def spine_lean(rotations: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(n, J, 4) local rotations and offsets (J, 3) or per row (n, J, 3) -> (n,) radians: the
    angle of the line from the spine's joint to the head's from straight up, towards the left
    of the hips' facing (``across.left_of_hips``), in the plane of that and up."""
    rotations = np.asarray(rotations, np.float64)
    world = rot.multiply(rotations[:, HIPS_INDEX], rotations[:, SPINE_INDEX])
    head = np.zeros((len(rotations), 3))
    for j in _UP_THE_SPINE:
        head = head + rot.apply(world, offsets[..., j, :])
        world = rot.multiply(world, rotations[:, j])
    left = left_of_hips(rotations)
    return np.arctan2(np.sum(head * left, axis=-1), head @ UP)


def leaned(rotations: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(n, J, 4) local rotations -> a copy with the spine turned about the level axis along
    the hips' facing so that ``spine_lean`` grows by ``angle`` (n,) radians, exactly; every
    other bone's local rotation as it was (the chest, arms and head ride on the spine)."""
    out = np.array(rotations, np.float64)
    hips = out[:, HIPS_INDEX]
    left = left_of_hips(out)
    # a turn about UP x left carries UP towards left: the lean grows by the angle
    turn = rot.exp_map(np.asarray(angle, np.float64)[:, None] * rot.cross(np.broadcast_to(UP, left.shape), left))
    out[:, SPINE_INDEX] = rot.multiply(rot.inverse(hips), rot.multiply(turn, rot.multiply(hips, out[:, SPINE_INDEX])))
    return out
