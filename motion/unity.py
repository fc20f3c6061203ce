"""The one place that converts between internal (BVH) space and Unity space.

Internal space (see ``motion.rotations``): right-handed, Y up, the performer faces +Z, so
the performer's left is +X; centimetres; quaternions (x, y, z, w).

Unity space (what VMC carries): left-handed, Y up, metres, quaternions (x, y, z, w). A
VRM avatar in Unity faces +Z in its T-pose and, Unity's +X being "right" for a viewer
behind it, the avatar's left is -X.

The conversion is the mirror M = diag(-1, 1, 1) (negate X) plus the unit change:

* positions: (x, y, z) cm  ->  (-x, y, z) / 100 m.
* rotations: a rotation R becomes M R M. For a quaternion with axis a and angle t, the
  mirrored rotation has axis det(M) * M a = (a_x, -a_y, -a_z) and the same angle, so
  (x, y, z, w) -> (x, -y, -z, w).

Why X and not Z (the other common choice, "negate position z and quaternion x, y"):
mirroring Z would keep the performer's left on +X but turn the performer to face -Z,
i.e. 180 degrees away from a VRM avatar's rest facing: the "avatar turned around"
complaint. Mirroring X keeps +Z as the facing in both spaces, so a T-pose is identity on
both sides, and it moves the performer's left to -X, which is exactly where an avatar's
left arm is in Unity: a raised left arm stays a raised left arm. The convention is pinned
by tests/test_unity.py with a known pose and with deliberately wrong conventions that
must fail.

Forward kinematics in Unity space is the same formula (world = parent * local, position
= parent position + parent rotation applied to the offset) with converted quantities,
because M R M composes as R does (M M = I).

Everything is vectorised over leading dimensions. The only other place that flips an axis is
``motion.mirror`` (the performer's mirror image, for training), with the same reflection.
"""

from __future__ import annotations

import numpy as np

from .rotations import X_REFLECTION

METRES_PER_CM = 0.01
_POSITION_TO_UNITY = np.array([-METRES_PER_CM, METRES_PER_CM, METRES_PER_CM])
_POSITION_FROM_UNITY = np.array([-100.0, 100.0, 100.0])
# Mirroring is an involution: the same sign pattern converts quaternions both ways.
_QUATERNION_MIRROR = X_REFLECTION


def position_to_unity(p_cm: np.ndarray) -> np.ndarray:
    """Internal positions or offsets (..., 3) in cm -> Unity (..., 3) in metres."""
    return np.asarray(p_cm, dtype=np.float64) * _POSITION_TO_UNITY


def position_from_unity(p_m: np.ndarray) -> np.ndarray:
    """Unity positions or offsets (..., 3) in metres -> internal (..., 3) in cm."""
    return np.asarray(p_m, dtype=np.float64) * _POSITION_FROM_UNITY


def rotation_to_unity(q: np.ndarray) -> np.ndarray:
    """Internal quaternions (..., 4) xyzw -> Unity quaternions (..., 4) xyzw."""
    return np.asarray(q, dtype=np.float64) * _QUATERNION_MIRROR


def rotation_from_unity(q: np.ndarray) -> np.ndarray:
    """Unity quaternions (..., 4) xyzw -> internal quaternions (..., 4) xyzw."""
    return np.asarray(q, dtype=np.float64) * _QUATERNION_MIRROR


def unity_euler_degrees(q_unity: np.ndarray) -> np.ndarray:
    """Unity quaternions (..., 4) -> Unity Euler angles (..., 3) = (x, y, z) in degrees.

    Unity's convention (``Quaternion.Euler``/``Transform.eulerAngles``): z about Z, then x
    about X, then y about Y, all about the fixed axes, i.e. q = Qy * Qx * Qz, which is the
    intrinsic "YXZ" sequence. VRChat's OSC trackers take rotations this way. Angles come
    in (-180, 180]; Unity reads any equivalent angle. Not an axis flip: the quaternion
    must already be in Unity space (``rotation_to_unity``)."""
    from .rotations import to_euler

    yxz = to_euler(q_unity, "YXZ")
    return yxz[..., [1, 0, 2]]
