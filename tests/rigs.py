"""Synthetic rigs written by the project itself (no copied data)."""

import numpy as np

from stylecast.motion import Skeleton
from stylecast.motion.humanoid import FOOT_PITCH_DEG

TOE_FORWARD = 6.0 / np.tan(np.radians(FOOT_PITCH_DEG))  # toe 6 cm below the ankle


def mocap_tpose_skeleton() -> Skeleton:
    """A common-mocap-named rig whose rest pose is a T-pose facing +Z (left = +X), feet
    pitched down by humanoid.FOOT_PITCH_DEG like the canonical T-pose."""
    joints = [
        ("Hips", None, (0, 0, 0)), ("Spine", "Hips", (0, 10, 0)), ("Spine1", "Spine", (0, 12, 0)),
        ("Neck", "Spine1", (0, 25, 0)), ("Head", "Neck", (0, 10, 0)),
        ("LeftShoulder", "Spine1", (3, 20, 0)), ("LeftArm", "LeftShoulder", (15, 0, 0)),
        ("LeftForeArm", "LeftArm", (28, 0, 0)), ("LeftHand", "LeftForeArm", (25, 0, 0)),
        ("RightShoulder", "Spine1", (-3, 20, 0)), ("RightArm", "RightShoulder", (-15, 0, 0)),
        ("RightForeArm", "RightArm", (-28, 0, 0)), ("RightHand", "RightForeArm", (-25, 0, 0)),
        ("LeftUpLeg", "Hips", (9, -5, 0)), ("LeftLeg", "LeftUpLeg", (0, -42, 0)),
        ("LeftFoot", "LeftLeg", (0, -40, 0)), ("LeftToeBase", "LeftFoot", (0, -6, TOE_FORWARD)),
        ("RightUpLeg", "Hips", (-9, -5, 0)), ("RightLeg", "RightUpLeg", (0, -42, 0)),
        ("RightFoot", "RightLeg", (0, -40, 0)), ("RightToeBase", "RightFoot", (0, -6, TOE_FORWARD)),
    ]
    return _skeleton(joints)


def bandai_like_skeleton() -> Skeleton:
    """The Bandai layout: a joint_Root above Hips and every bone along its local X axis
    at rest (so the rest pose is not a T-pose), left joints at -Y in the hips frame."""
    joints = [
        ("joint_Root", None, (0, 0, 0)), ("Hips", "joint_Root", (4.6, 91.5, -4.0)),
        ("Spine", "Hips", (15.7, 0, 0)), ("Chest", "Spine", (9.0, -0.4, 0)), ("Neck", "Chest", (16.4, 0, 0)),
        ("Head", "Neck", (6.5, 0, 0)),
        ("Shoulder_L", "Chest", (13.0, -0.2, 5.0)), ("UpperArm_L", "Shoulder_L", (5.3, 0, 0)),
        ("LowerArm_L", "UpperArm_L", (24.3, 0, 0)), ("Hand_L", "LowerArm_L", (22.3, 0, 0)),
        ("Shoulder_R", "Chest", (13.0, -0.2, -5.0)), ("UpperArm_R", "Shoulder_R", (-5.3, 0, 0)),
        ("LowerArm_R", "UpperArm_R", (-24.3, 0, 0)), ("Hand_R", "LowerArm_R", (-22.3, 0, 0)),
        ("UpperLeg_L", "Hips", (-2.2, -6.5, 0)), ("LowerLeg_L", "UpperLeg_L", (39.1, 0, 0)),
        ("Foot_L", "LowerLeg_L", (41.0, 0, 0)), ("Toes_L", "Foot_L", (11.8, 0, 0)),
        ("UpperLeg_R", "Hips", (-2.2, 6.5, 0)), ("LowerLeg_R", "UpperLeg_R", (-39.1, 0, 0)),
        ("Foot_R", "LowerLeg_R", (-41.0, 0, 0)), ("Toes_R", "Foot_R", (-11.8, 0, 0)),
    ]
    return _skeleton(joints, six_channels=True)


def _skeleton(joints, six_channels=False) -> Skeleton:
    names = [n for n, _, _ in joints]
    parents = [-1 if p is None else names.index(p) for _, p, _ in joints]
    pos = ("Xposition", "Yposition", "Zposition")
    rot = ("Zrotation", "Xrotation", "Yrotation")
    channels = [pos + rot if (six_channels or p < 0) else rot for p in parents]
    return Skeleton(tuple(names), tuple(parents), np.array([o for _, _, o in joints], float), tuple(channels))
