"""Synthetic motion the foot lock's tests share: a standing figure that steps, restyles that lean,
spread and crouch it, the lock settings of --feet, and a joint's horizontal speed."""

from __future__ import annotations

import numpy as np

from stylecast.motion import rotations as rot
from stylecast.motion.footlock import FEET
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default


J = len(HUMANOID_BONES)
SK = humanoid_skeleton_default()


def stepping(frames: int = 240):
    """A standing figure lifting its right foot for half a second every second: the left
    foot stays planted, the right one plants and lifts. Returns (roots, rotations)."""
    t = np.arange(frames) / 60.0
    q = np.tile(rot.identity((J,)), (frames, 1, 1))
    lift = np.clip(np.sin(2 * np.pi * t), 0, None)  # half of each second up
    right_up, right_knee = HUMANOID_BONES.index("RightUpperLeg"), HUMANOID_BONES.index("RightLowerLeg")
    q[:, right_up] = rot.exp_map(np.stack([-0.9 * lift, 0 * t, 0 * t], -1))  # thigh forward
    q[:, right_knee] = rot.exp_map(np.stack([1.4 * lift, 0 * t, 0 * t], -1))  # knee bent back
    # The standing knees are soft (a straight leg cannot reach any further when the
    # restyled hips move away from its foot).
    for side, sign in (("Left", 1.0), ("Right", 1.0)):
        for bone, angle in (("UpperLeg", -0.2), ("LowerLeg", 0.4)):
            j = HUMANOID_BONES.index(f"{side}{bone}")
            q[:, j] = rot.multiply(q[:, j], rot.exp_map(np.array([sign * angle, 0.0, 0.0])))
    # the ground: default humanoid legs hang 82 cm and the ball sits a foot-height lower
    roots = np.stack([0 * t, 100.0 + 0 * t, 0 * t], -1)
    return roots, q


def restyled(q: np.ndarray, degrees: float = 12.0) -> np.ndarray:
    """A 'restyle' that leans the hips and bends both legs differently (feet would slide)."""
    out = q.copy()
    wobble = np.radians(degrees) * np.sin(np.arange(len(q)) / 9.0)
    for bone, axis in (("Hips", 0), ("LeftUpperLeg", 0), ("LeftLowerLeg", 0), ("RightUpperLeg", 2)):
        v = np.zeros((len(q), 3))
        v[:, axis] = wobble
        j = HUMANOID_BONES.index(bone)
        out[:, j] = rot.multiply(out[:, j], rot.exp_map(v))
    return out


def horizontal_speed(p: np.ndarray) -> np.ndarray:
    """(n, 2, 3) positions -> (n - 1, 2) cm per frame on the floor plane."""
    return np.linalg.norm(np.diff(p[..., [0, 2]], axis=0), axis=-1)


def spread(q: np.ndarray, degrees: np.ndarray) -> np.ndarray:
    """A 'restyle' into a wider stance: each thigh rolled outwards by ``degrees`` (per frame)."""
    out = q.copy()
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        j = HUMANOID_BONES.index(f"{side}UpperLeg")
        v = np.zeros((len(q), 3))
        v[:, 2] = sign * np.radians(degrees)
        out[:, j] = rot.multiply(out[:, j], rot.exp_map(v))
    return out


ON_INPUT_ANKLES, STANCE = FEET["input"], FEET["stance"]  # --feet input (the default), --feet stance
ON_INPUT_PATH = FEET["path"]  # --feet path


def crouched(q: np.ndarray, degrees: float = 15.0) -> np.ndarray:
    """A 'restyle' into a lower stance: both thighs forward by an angle and both knees
    bent back by twice that, so each ankle ends up nearly straight above where the input
    put it (thigh and shin are about as long), centimetres up (the root did not move)."""
    out = q.copy()
    a = np.radians(degrees)
    for side in ("Left", "Right"):
        for bone, angle in (("UpperLeg", -a), ("LowerLeg", 2 * a)):
            j = HUMANOID_BONES.index(f"{side}{bone}")
            out[:, j] = rot.multiply(out[:, j], rot.exp_map(np.array([angle, 0.0, 0.0])))
    return out
