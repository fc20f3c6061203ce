"""Rotation helpers and the conventions every part of stylecast follows.

Conventions (stated once, here):

* Quaternions are stored (x, y, z, w), scalar last, as in VMC and scipy.
* Internal space is BVH space: right-handed, Y up, the performer facing +Z in the T-pose
  (so the performer's left is +X), lengths in centimetres. Unity space (left-handed,
  metres) exists only in ``motion.unity``; the one other thing that flips an axis is the
  performer's mirror image for training (``motion.mirror``). Both negate X, so both reflect
  a quaternion with ``X_REFLECTION``.
* Euler orders are written as BVH channel orders ("ZXY" = the channels Zrotation,
  Xrotation, Yrotation in that order) and mean intrinsic rotations applied in that order:
  R = Rz @ Rx @ Ry for "ZXY". That is scipy's upper-case (intrinsic) convention.
  Angles are degrees.
* A local rotation maps a joint's frame into its parent's frame; a world (global)
  rotation maps it into the world frame: world[j] = world[parent] * local[j].

All functions take arrays of any leading shape (..., 4) and are vectorised over it. Euler
conversion and vector rotation are scipy's ``Rotation``; the product and slerp, which run
per frame per performer, and Euler-to-quaternion, which runs per value of every file
read, are written out in numpy and tested against scipy.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
# A rotation R under the reflection M = diag(-1, 1, 1) becomes M R M: for a quaternion with
# axis a and angle t, axis det(M) M a = (a_x, -a_y, -a_z) and the same angle, so (x, y, z, w)
# -> (x, -y, -z, w). Its own inverse.
X_REFLECTION = np.array([1.0, -1.0, -1.0, 1.0])


def _flat(q: np.ndarray) -> tuple[Rotation, tuple[int, ...]]:
    q = np.asarray(q, dtype=np.float64)
    return Rotation.from_quat(q.reshape(-1, 4)), q.shape[:-1]


def identity(shape: tuple[int, ...] = ()) -> np.ndarray:
    return np.broadcast_to(IDENTITY, (*shape, 4)).copy()


def from_euler(angles_deg: np.ndarray, order: str) -> np.ndarray:
    """Euler angles (..., 3) in channel ``order`` (e.g. "ZXY") to quaternions (..., 4).

    The product of the three axis quaternions, written out: scipy's from_euler costs
    ~1.7 us per rotation (more than parsing a BVH file's numbers), this ~0.1 us.
    tests/test_rotations.py checks it against scipy for all six orders.
    """
    angles = np.asarray(angles_deg, dtype=np.float64)
    half = np.radians(angles) * 0.5
    sin, cos = np.sin(half), np.cos(half)
    order = order.upper()
    q = [np.zeros(angles.shape[:-1]) for _ in range(4)]  # x, y, z, w
    first = "XYZ".index(order[0])
    q[first], q[3] = sin[..., 0], cos[..., 0]
    for k in (1, 2):
        # q * (sin * axis_i, cos): with (i, j, l) the axis and the two after it, cyclically,
        # only four products survive.
        i = "XYZ".index(order[k])
        j, l = (i + 1) % 3, (i + 2) % 3  # noqa: E741
        s, c = sin[..., k], cos[..., k]
        q[i], q[j], q[l], q[3] = q[3] * s + q[i] * c, q[j] * c + q[l] * s, q[l] * c - q[j] * s, q[3] * c - q[i] * s
    return np.stack(q, axis=-1)


def to_euler(q: np.ndarray, order: str) -> np.ndarray:
    """Quaternions (..., 4) to Euler angles (..., 3) in degrees, channel ``order``."""
    r, shape = _flat(q)
    import warnings

    with warnings.catch_warnings():
        # Gimbal lock is a property of the representation, not an error: scipy still
        # returns a valid decomposition (third angle zero).
        warnings.simplefilter("ignore", UserWarning)
        e = r.as_euler(order.upper(), degrees=True)
    return e.reshape(*shape, 3)


# q_a * q_b = L(q_a) @ q_b with L(q_a) the 4x4 left-multiplication matrix of q_a, built
# by one gather and one sign flip: three numpy calls whatever the batch shape.
_LEFT_INDEX = np.array([[3, 2, 1, 0], [2, 3, 0, 1], [1, 0, 3, 2], [0, 1, 2, 3]])
_LEFT_SIGN = np.array([[1.0, -1.0, 1.0, 1.0], [1.0, 1.0, -1.0, 1.0], [-1.0, 1.0, 1.0, 1.0], [-1.0, -1.0, -1.0, 1.0]])


def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b (apply b first, then a), broadcasting leading shapes.

    Written out in numpy rather than through scipy's Rotation because it is on the
    per-frame path of every performer, where building Rotation objects dominated (measured
    ~4x slower for a 22-bone pose). tests/test_rotations.py checks it against scipy.
    """
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    return (a[..., _LEFT_INDEX] * _LEFT_SIGN @ b[..., None])[..., 0]


def inverse(q: np.ndarray) -> np.ndarray:
    """The inverse rotation (the conjugate, divided by the squared norm)."""
    q = np.asarray(q, dtype=np.float64)
    return q * np.array([-1.0, -1.0, -1.0, 1.0]) / np.sum(q * q, axis=-1, keepdims=True)


def apply(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors (..., 3) by unit quaternions (..., 4), broadcasting leading shapes.

    v' = v + 2 w (u x v) + 2 u x (u x v) with q = (u, w), in numpy: on the per-frame path
    (forward kinematics of the foot lock), where building a scipy Rotation per call cost
    ten times the arithmetic. tests/test_rotations.py checks it against scipy."""
    q = np.asarray(q, np.float64)
    v = np.asarray(v, np.float64)
    u, w = q[..., :3], q[..., 3:]
    uv = cross(u, v)
    return v + 2.0 * (w * uv + cross(u, uv))


_NEXT, _AFTER = np.array([1, 2, 0]), np.array([2, 0, 1])  # (y, z, x) and (z, x, y)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis, broadcasting. Written out because np.cross's
    general axis handling costs ~10x the arithmetic on the small per-frame arrays; the
    cyclic ``take`` form runs 3 us on a (1, 2, 3) pair where components stacked back
    together ran 15 (np.cross: 39), and 1.7x faster on 1,000 rows too."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    return a.take(_NEXT, axis=-1) * b.take(_AFTER, axis=-1) - a.take(_AFTER, axis=-1) * b.take(_NEXT, axis=-1)


def exp_map(rotvec: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) (axis times angle in radians) to quaternions (..., 4)."""
    v = np.asarray(rotvec, np.float64)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    # sin(angle/2)/angle, with its limit 1/2 - angle^2/48 near zero.
    scale = np.where(angle < 1e-6, 0.5 - angle * angle / 48.0, np.sin(0.5 * angle) / np.where(angle < 1e-6, 1.0, angle))
    return np.concatenate([v * scale, np.cos(0.5 * angle)], axis=-1)


def log_map(q: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) to rotation vectors (..., 3) of the short arc (angle <= pi)."""
    q = np.asarray(q, np.float64)
    q = np.where(q[..., 3:] < 0.0, -q, q)
    s = np.linalg.norm(q[..., :3], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., 3:])
    scale = np.where(s < 1e-12, 2.0, angle / np.where(s < 1e-12, 1.0, s))
    return q[..., :3] * scale


def slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray | float) -> np.ndarray:
    """Element-wise spherical interpolation from q0 (t=0) to q1 (t=1) along the short arc.

    Hand-written for the same per-frame reason as ``multiply``; checked against scipy's
    Slerp in tests/test_rotations.py. Inputs must be unit quaternions.
    """
    q0 = np.asarray(q0, np.float64)
    q1 = np.asarray(q1, np.float64)
    t = np.asarray(t, np.float64)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0.0, -q1, q1)  # short arc
    dot = np.clip(np.abs(dot), 0.0, 1.0)
    theta = np.arccos(dot)
    sin_theta = np.sin(theta)
    small = sin_theta < 1e-6  # nearly equal: linear interpolation is exact to rounding
    safe = np.where(small, 1.0, sin_theta)
    w0 = np.where(small, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    w1 = np.where(small, t, np.sin(t * theta) / safe)
    out = w0 * q0 + w1 * q1
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def angle_between(q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """Geodesic angle in degrees between two rotations (element-wise).

    atan2 of the relative rotation's vector and scalar parts stays accurate near zero,
    where arccos of a dot product loses half the digits."""
    rel = multiply(inverse(q0), q1)
    return np.degrees(2.0 * np.arctan2(np.linalg.norm(rel[..., :3], axis=-1), np.abs(rel[..., 3])))


def swing(from_dir: np.ndarray, to_dir: np.ndarray, fallback_axis: np.ndarray) -> np.ndarray:
    """The smallest rotation turning ``from_dir`` onto ``to_dir`` (both 3-vectors).

    Near opposite directions the smallest rotation's axis is numerically arbitrary (a
    rest pose with a leg pointing up along the spine would flip the knee at random).
    There the rotation is built as 180 degrees about ``fallback_axis`` (made
    perpendicular to ``from_dir``) followed by the small remaining swing, so callers keep
    a limb in a chosen plane.
    """
    a = np.asarray(from_dir, np.float64) / np.linalg.norm(from_dir)
    b = np.asarray(to_dir, np.float64) / np.linalg.norm(to_dir)
    if np.dot(a, b) < -0.9:  # within ~25 degrees of opposite
        f = np.asarray(fallback_axis, np.float64)
        f = f - np.dot(f, a) * a
        half_turn = Rotation.from_rotvec(np.pi * f / np.linalg.norm(f)).as_quat()
        return multiply(swing(apply(half_turn, a), b, fallback_axis), half_turn)
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(np.dot(a, b))
    if s < 1e-12:
        return IDENTITY.copy()
    return Rotation.from_rotvec(axis / s * np.arctan2(s, c)).as_quat()


def canonical_hemisphere(q: np.ndarray, axis: int = 0) -> np.ndarray:
    """Flip signs along a time ``axis`` so consecutive quaternions have a positive dot.

    q and -q are the same rotation; interpolation and finite differences need the
    representative that is continuous in time.
    """
    q = np.array(q, dtype=np.float64, copy=True)
    # Time first as a view, so the flips land in q itself (moveaxis was a fifth of this
    # function's cost on one word, which the daemon pays per word and performer).
    t = q if axis == 0 else np.moveaxis(q, axis, 0)
    if len(t) > 1:
        # The four products summed in order, as np.sum does over a length-4 axis (so the
        # signs are bit for bit the same) but without a reduction over a tiny inner axis,
        # which cost most of offline restyling's word cutting.
        a, b = t[1:], t[:-1]
        dots = a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2] + a[..., 3] * b[..., 3]
        flips = np.cumprod(np.where(dots < 0, -1.0, 1.0), axis=0)
        t[1:] *= flips[..., None]
    return q


# Shorter than this, a "quaternion" a model returned is no rotation (a fault, not a pose).
MIN_QUATERNION_NORM = 1e-6


def usable_words(words: np.ndarray) -> np.ndarray:
    """(B, T, J, 4) -> (B,) bool: every quaternion of the word finite and of non-zero length."""
    words = np.asarray(words)
    norms = np.linalg.norm(words, axis=-1)
    return np.all(np.isfinite(words), axis=(1, 2, 3)) & np.all(norms > MIN_QUATERNION_NORM, axis=(1, 2))
