"""From humanoid local rotations to the capsules the scene draws (metres, world space).

Forward kinematics is batched over the performers of one draw call, so the per-joint scipy
calls are paid once per frame for all performers that share a skeleton.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scipy.spatial.transform import Rotation

from stylecast.motion.humanoid import TPOSE_DIRECTION
from stylecast.motion.skeleton import Skeleton

CM_TO_M = 0.01  # internal space is centimetres; the scene, its grid and camera are metres

# Capsule radius (m) of the segment that ends at each bone (parent joint -> this joint), so
# "LowerArm" is the upper arm (UpperArm joint -> LowerArm joint). Keyed by the child because
# Hips and UpperChest branch: their segments to different children differ in size.
SEGMENT_RADIUS = {
    "Spine": 0.065, "Chest": 0.065, "UpperChest": 0.07, "Neck": 0.06, "Head": 0.04,
    "Shoulder": 0.045, "UpperArm": 0.04, "LowerArm": 0.04, "Hand": 0.034,
    "UpperLeg": 0.06, "LowerLeg": 0.058, "Foot": 0.046, "Toes": 0.038,
}
# Bones with no child in the humanoid hierarchy still have a body part beyond the joint:
# (length m, radius m) drawn along the bone's T-pose direction in its own frame (identity =
# T-pose with world-aligned axes, so that direction is the bone's axis).
TIP = {"Head": (0.13, 0.085), "LeftHand": (0.08, 0.032), "RightHand": (0.08, 0.032),
       "LeftToes": (0.05, 0.032), "RightToes": (0.05, 0.032)}


def _short(name: str) -> str:
    return name.removeprefix("Left").removeprefix("Right")


@dataclass(frozen=True, eq=False)
class BoneLayout:
    """Which segments a skeleton has: (parent, child) joint pairs and end tips."""

    pairs: np.ndarray  # (S, 2) joint indices
    pair_radius: np.ndarray  # (S,)
    tips: np.ndarray  # (K,) joint indices
    tip_vectors: np.ndarray  # (K, 3) tip offset in the joint's frame, metres
    tip_radius: np.ndarray  # (K,)

    @property
    def count(self) -> int:
        return len(self.pairs) + len(self.tips)

    @classmethod
    def for_skeleton(cls, skeleton: Skeleton) -> "BoneLayout":
        pairs, radius = [], []
        for j, p in enumerate(skeleton.parents):
            # A zero-length offset (a bone the source lacks sits on its parent) has no body.
            if p >= 0 and np.linalg.norm(skeleton.offsets[j]) * CM_TO_M > 1e-3:
                pairs.append((p, j))
                radius.append(SEGMENT_RADIUS.get(_short(skeleton.names[j]), 0.04))
        tips = [(skeleton.index(b), *TIP[b]) for b in TIP if skeleton.get(b) is not None]
        tip_dir = [np.asarray(TPOSE_DIRECTION.get(skeleton.names[j], (0, 1, 0))) * length for j, length, _ in tips]
        return cls(np.array(pairs, dtype=np.int64).reshape(-1, 2), np.array(radius, dtype=np.float32),
                   np.array([t[0] for t in tips], dtype=np.int64),
                   np.array(tip_dir, dtype=np.float64).reshape(-1, 3),
                   np.array([t[2] for t in tips], dtype=np.float32))


def pose_world(skeleton: Skeleton, root_positions: np.ndarray, rotations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World joint positions (P, J, 3) in metres and world rotation matrices (P, J, 3, 3)
    for P poses of one skeleton.

    The same maths as ``motion.clip.forward_kinematics``, done on matrices: scipy converts
    every quaternion in one call, then each joint is one batched matrix product over all
    performers. Measured on this project's 2-core machine: about 10x cheaper than a pair of
    scipy ``Rotation`` calls per joint, which is what keeps 8 performers within a frame.
    """
    rotations = np.asarray(rotations, np.float64)
    P, J = rotations.shape[:2]
    local = Rotation.from_quat(rotations.reshape(-1, 4)).as_matrix().reshape(P, J, 3, 3)
    offsets = skeleton.offsets * CM_TO_M
    positions = np.empty((P, J, 3))
    world = np.empty((P, J, 3, 3))
    for j, p in enumerate(skeleton.parents):
        if p < 0:
            world[:, j] = local[:, j]
            positions[:, j] = np.asarray(root_positions, np.float64) * CM_TO_M
        else:
            world[:, j] = world[:, p] @ local[:, j]
            positions[:, j] = positions[:, p] + world[:, p] @ offsets[j]
    return positions, world


def capsules(layout: BoneLayout, positions: np.ndarray, world: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """End points a, b (P, S+K, 3) and radius (S+K,) of every capsule of P poses."""
    a = positions[:, layout.pairs[:, 0]]
    b = positions[:, layout.pairs[:, 1]]
    tip_a = positions[:, layout.tips]
    tip_b = tip_a + np.einsum("pkij,kj->pki", world[:, layout.tips], layout.tip_vectors)
    return (np.concatenate([a, tip_a], axis=1), np.concatenate([b, tip_b], axis=1),
            np.concatenate([layout.pair_radius, layout.tip_radius]))
