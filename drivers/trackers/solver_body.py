"""The body the solver works on: bone and role indices, the four limbs, the spine chain,
forward kinematics over arrays, and tracker frames as arrays.

Shared by calibration, the hold and the IK (``solver_calibration``, ``solver_hold``,
``solver_ik``); depends on nothing of theirs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stylecast.motion import rotations as rot
from stylecast.motion.humanoid import HUMANOID_BONES, HUMANOID_PARENTS

from stylecast.drivers.trackers.trackers import ALL_ROLES, TrackerRole

B = {name: i for i, name in enumerate(HUMANOID_BONES)}
R = TrackerRole
N_ROLES = len(ALL_ROLES)
N_BONES = len(HUMANOID_BONES)
SPINE = ("Spine", "Chest", "UpperChest", "Neck")
# Cumulative share of the hips->head rotation (beyond neutral) carried by each spine bone's
# world frame; the head carries the rest.
SPINE_WEIGHTS = (0.35, 0.65, 0.8, 0.9)
DEFAULT_BLEND_TIME = 0.3  # seconds from a held pose back to the live one
POLE_HINT_CM = 1.5  # weight of the usual elbow / knee direction next to the pole target
HELD_POLE_HINT_CM = 40.0  # ... added while the hand / foot is held


@dataclass(frozen=True)
class _Limb:
    root: str  # Shoulder (clavicle) for arms, "" for legs
    upper: str
    lower: str
    end: str
    tip: str | None  # bone after ``end`` (toes) or None
    pole_role: TrackerRole
    end_role: TrackerRole


LIMBS = (
    _Limb("LeftShoulder", "LeftUpperArm", "LeftLowerArm", "LeftHand", None, R.LEFT_ELBOW, R.LEFT_HAND),
    _Limb("RightShoulder", "RightUpperArm", "RightLowerArm", "RightHand", None, R.RIGHT_ELBOW, R.RIGHT_HAND),
    _Limb("", "LeftUpperLeg", "LeftLowerLeg", "LeftFoot", "LeftToes", R.LEFT_KNEE, R.LEFT_FOOT),
    _Limb("", "RightUpperLeg", "RightLowerLeg", "RightFoot", "RightToes", R.RIGHT_KNEE, R.RIGHT_FOOT),
)


def _chain(bone: int) -> list[int]:
    """Bones from the first below Hips down to ``bone`` (whose offsets place its joint)."""
    out = []
    while bone > 0:
        out.append(bone)
        bone = HUMANOID_PARENTS[bone]
    return out[::-1]


def _local_to_world(local: np.ndarray) -> np.ndarray:
    world = np.empty_like(local)
    for j, p in enumerate(HUMANOID_PARENTS):
        world[..., j, :] = local[..., j, :] if p < 0 else rot.multiply(world[..., p, :], local[..., j, :])
    return world


def _fk_positions(world: np.ndarray, hips: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    pos = np.empty(world.shape[:-1] + (3,))
    for j, p in enumerate(HUMANOID_PARENTS):
        pos[..., j, :] = hips if p < 0 else pos[..., p, :] + rot.apply(world[..., p, :], offsets[j])
    return pos


def _as_arrays(frames) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """TrackerPoses list or a (timestamps, positions, orientations, valid) tuple -> arrays."""
    if isinstance(frames, tuple):
        ts, p, q, v = frames
        return (np.asarray(ts, float), np.asarray(p, float), np.asarray(q, float), np.asarray(v, bool))
    frames = list(frames)
    return (np.array([f.timestamp for f in frames], float), np.stack([f.positions for f in frames]),
            np.stack([f.orientations for f in frames]), np.stack([f.valid for f in frames]))
