"""Elbows and knees bend one way: the restyle may not bend them sideways or past straight.

In the humanoid's frames (``humanoid``: T-pose relative, world-aligned, arms along X, legs
along -Y) every elbow and knee of the Bandai data is a hinge: a lower arm turns about its
own axis (the forearm's twist) and flexes about Y, a lower leg flexes about X, and nothing
else moves them (on the held-out clips the sideways bend stays within 0.1 degrees and a
knee's twist within about half a degree, 1st to 99th percentile).
The generator's correction is a free rotation per bone, and the shipped model used that
freedom: on the held-out normal clips its elbows bent sideways by up to 11 degrees and
past straight by 4, its knees sideways by 3.5 and twisted by 3 (1st / 99th percentiles),
poses no performer made (``models/checkpoints/MODEL_CARD.md``, "Elbows and knees").

``keep_hinges`` takes each hinge bone's rotation apart as swing * twist about the bone's
axis, the swing as a rotation vector (perpendicular to the bone), and keeps from the
restyle only what the joint can do: the flexion, and the forearm's twist. The rest (the
sideways bend, a knee's twist) is the input's, so an input that is no hinge (a tracker
solve, another rig) keeps its own, and the flexion may not pass straight unless the input
does, then no further than the input. Per frame and stateless: ``restyle`` and ``serve``
run it on the same frames after the correction low-pass, before the foot lock.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from . import rotations as rot
from .humanoid import HUMANOID_BONES


class Hinge(NamedTuple):
    bone: str
    axis: int  # the bone's own axis (X, Y, Z = 0, 1, 2): its twist is about it
    flexion: int  # the axis the joint bends about
    bent: float  # the sign of the flexion of a bent joint (straight is 0)
    twists: bool  # whether the restyle may turn the bone about its own axis (a forearm: yes)


HINGES = (Hinge("LeftLowerArm", 0, 1, -1.0, True), Hinge("RightLowerArm", 0, 1, 1.0, True),
          Hinge("LeftLowerLeg", 1, 0, 1.0, False), Hinge("RightLowerLeg", 1, 0, 1.0, False))


def _swing_twist(q: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """q (..., 4) xyzw -> (swing as a rotation vector (..., 3), perpendicular to the axis;
    the twist about the axis (..., 4)), q = exp(swing) * twist."""
    twist = np.zeros_like(q)
    twist[..., axis] = q[..., axis]
    twist[..., 3] = q[..., 3]
    norm = np.linalg.norm(twist, axis=-1, keepdims=True)
    # A rotation by 180 degrees about a perpendicular axis has no twist to speak of.
    twist = np.where(norm > 1e-12, twist / np.maximum(norm, 1e-12), rot.identity(q.shape[:-1]))
    swing = rot.log_map(rot.multiply(q, rot.inverse(twist)))
    swing[..., axis] = 0.0  # it is, to rounding
    return swing, twist


def keep_hinges(inputs: np.ndarray, outputs: np.ndarray, hinges=HINGES, bones=HUMANOID_BONES) -> np.ndarray:
    """Humanoid rotations (..., J, 4): the inputs and the restyle's outputs -> the outputs
    with each hinge bone keeping only the flexion (and a forearm's twist) of the restyle.
    Rotations of another skeleton (the tests' small synthetic streams) pass unchanged."""
    inputs = np.asarray(inputs, dtype=np.float64)
    out = np.array(outputs, dtype=np.float64)
    if inputs.shape[-2] != len(bones):
        return out
    for hinge in hinges:
        j = bones.index(hinge.bone)
        swing_in, twist_in = _swing_twist(inputs[..., j, :], hinge.axis)
        swing_out, twist_out = _swing_twist(out[..., j, :], hinge.axis)
        swing = swing_in.copy()  # the sideways bend: the input's
        bend_in = hinge.bent * swing_in[..., hinge.flexion]
        bend = np.maximum(hinge.bent * swing_out[..., hinge.flexion], np.minimum(bend_in, 0.0))
        swing[..., hinge.flexion] = hinge.bent * bend
        q = rot.multiply(rot.exp_map(swing), twist_out if hinge.twists else twist_in)
        out[..., j, :] = np.where(np.sum(q * out[..., j, :], axis=-1, keepdims=True) < 0, -q, q)
    return out
