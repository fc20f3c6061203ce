"""The performer's left-right mirror image of humanoid motion.

A humanoid's local rotations are relative to a T-pose in world-aligned bone frames
(``motion.humanoid``), and that T-pose is its own mirror image. So the mirror image of a
motion (the reflection M = diag(-1, 1, 1) across the body's sagittal plane, X being the
performer's left) is, bone by bone: the rotation of the bone on the other side, reflected.
A rotation R reflects to M R M, (x, y, z, w) -> (x, -y, -z, w) (``rotations.X_REFLECTION``).
Forward kinematics of the result is the original's joint positions with x negated, up to
the difference in length between a bone and its twin (``tests/test_mirror.py``).

The same reflection converts to Unity space (``motion.unity``), where it means something
else: a change of handedness, not of the performer's side.
"""

from __future__ import annotations

import numpy as np

from .humanoid import HUMANOID_BONES
from .rotations import X_REFLECTION

SIDES = ("Left", "Right")


def _twin(bone: str) -> str:
    for side, other in (SIDES, SIDES[::-1]):
        if bone.startswith(side):
            return other + bone[len(side):]
    return bone


# MIRROR_BONES[j]: the index of bone j's twin on the other side (its own for the spine).
MIRROR_BONES = np.array([HUMANOID_BONES.index(_twin(b)) for b in HUMANOID_BONES])


def reflect_rotations(q: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) xyzw -> their reflections M R M."""
    return np.asarray(q) * X_REFLECTION.astype(np.asarray(q).dtype)


def mirror_rotations(local: np.ndarray) -> np.ndarray:
    """Humanoid local rotations (..., J, 4) -> the mirror image's, same dtype."""
    local = np.asarray(local)
    return reflect_rotations(local[..., MIRROR_BONES, :])


def mirror_positions(p: np.ndarray) -> np.ndarray:
    """Positions (..., 3) -> the mirror image's (x negated)."""
    return np.asarray(p) * np.array([-1.0, 1.0, 1.0], dtype=np.asarray(p).dtype)
