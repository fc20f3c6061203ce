"""Vector and quaternion algebra for the solver, written once for two kinds of numbers.

Conventions are those of ``motion.rotations`` (quaternions x, y, z, w).

The IK (``solver_ik``) runs on one live frame at a time, where numpy's per-call cost
(about a microsecond on a 4-element array, measured) is 10-50x the arithmetic, and on whole
recordings, where numpy is what makes it fast. So the IK is written on *components*:
a vector is a tuple (x, y, z), a quaternion (x, y, z, w), and each component is either a
Python float (one frame: ``SCALAR``) or a numpy array over frames (``ARRAY``). The
arithmetic operators work on both; the few functions and branches that differ come from
the backend object ``xp``. Same code, same operation order: the two paths agree to the
last bit on + - * / sqrt and to an ulp where libm and numpy's sin/cos/atan2 differ.

The array-of-structures helpers at the end (``_unit``, ``_swing``, ``_align``, ...) take
(..., 3) / (..., 4) arrays as the rest of stylecast does; calibration and the hold use
them, and they go through the component code so there is one implementation of each.
"""

from __future__ import annotations

import math

import numpy as np

from stylecast.motion import rotations as rot

# ------------------------------------------------------------------ backends


class _Scalar:
    """Python floats: one frame."""

    sqrt, sin, cos, atan2 = (staticmethod(f) for f in (math.sqrt, math.sin, math.cos, math.atan2))

    @staticmethod
    def select(cond, a, b):
        return a if cond else b

    @staticmethod
    def any(cond) -> bool:
        return bool(cond)

    maximum = max  # (a builtin: does not bind as a method)

    @staticmethod
    def clip(x, lo, hi):  # np.clip: min(max(x, lo), hi)
        x = lo if x < lo else x
        return hi if x > hi else x

    @staticmethod
    def exp_map(v, s=1.0):
        """The quaternion of the rotation vector s v."""
        x, y, z = v[0] * s, v[1] * s, v[2] * s
        angle = math.sqrt(x * x + y * y + z * z)
        # sin(angle/2)/angle, with its limit 1/2 - angle^2/48 near zero (as rotations.exp_map).
        k = 0.5 - angle * angle / 48.0 if angle < 1e-6 else math.sin(0.5 * angle) / angle
        return x * k, y * k, z * k, math.cos(0.5 * angle)

    @staticmethod
    def log_map(q):
        x, y, z, w = q
        if w < 0.0:  # the short arc
            x, y, z, w = -x, -y, -z, -w
        s = math.sqrt(x * x + y * y + z * z)
        k = 2.0 if s < 1e-12 else 2.0 * math.atan2(s, w) / s
        return x * k, y * k, z * k

    @staticmethod
    def matrix_to_quat(m):
        """Shepperd's method, as scipy's Rotation.from_matrix (the same sign choice)."""
        m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
        tr = m00 + m11 + m22
        best, choice = m00, 0  # argmax of (m00, m11, m22, trace), the first of equals
        if m11 > best:
            best, choice = m11, 1
        if m22 > best:
            best, choice = m22, 2
        if tr > best:
            choice = 3
        if choice == 0:
            q = (1.0 - tr + 2.0 * m00, m10 + m01, m20 + m02, m21 - m12)
        elif choice == 1:
            q = (m10 + m01, 1.0 - tr + 2.0 * m11, m21 + m12, m02 - m20)
        elif choice == 2:
            q = (m20 + m02, m21 + m12, 1.0 - tr + 2.0 * m22, m10 - m01)
        else:
            q = (m21 - m12, m02 - m20, m10 - m01, 1.0 + tr)
        n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        return q[0] / n, q[1] / n, q[2] / n, q[3] / n


class _Array:
    """numpy arrays over frames (any shape, broadcasting)."""

    # staticmethod: some numpy functions are Python functions, which would bind as methods.
    sqrt, sin, cos, atan2 = (staticmethod(f) for f in (np.sqrt, np.sin, np.cos, np.arctan2))
    select, maximum, clip = staticmethod(np.where), staticmethod(np.maximum), staticmethod(np.clip)

    @staticmethod
    def any(cond) -> bool:
        return bool(np.any(cond))

    @staticmethod
    def exp_map(v, s=1.0):
        x, y, z = v[0] * s, v[1] * s, v[2] * s
        angle = np.sqrt(x * x + y * y + z * z)
        small = angle < 1e-6
        k = np.where(small, 0.5 - angle * angle / 48.0, np.sin(0.5 * angle) / np.where(small, 1.0, angle))
        return x * k, y * k, z * k, np.cos(0.5 * angle)

    @staticmethod
    def log_map(q):
        x, y, z, w = q
        sign = np.where(w < 0.0, -1.0, 1.0)
        x, y, z, w = x * sign, y * sign, z * sign, w * sign
        s = np.sqrt(x * x + y * y + z * z)
        small = s < 1e-12
        k = np.where(small, 2.0, 2.0 * np.arctan2(s, w) / np.where(small, 1.0, s))
        return x * k, y * k, z * k

    @staticmethod
    def matrix_to_quat(m):
        m00, m01, m02, m10, m11, m12, m20, m21, m22 = np.broadcast_arrays(*m)
        tr = m00 + m11 + m22
        choice = np.argmax(np.stack([m00, m11, m22, tr]), axis=0)  # first of equals, as scipy
        cases = (
            (1.0 - tr + 2.0 * m00, m10 + m01, m20 + m02, m21 - m12),
            (m10 + m01, 1.0 - tr + 2.0 * m11, m21 + m12, m02 - m20),
            (m20 + m02, m21 + m12, 1.0 - tr + 2.0 * m22, m10 - m01),
            (m21 - m12, m02 - m20, m10 - m01, 1.0 + tr),
        )
        q = [np.choose(choice, [c[i] for c in cases]) for i in range(4)]
        n = np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        return q[0] / n, q[1] / n, q[2] / n, q[3] / n


SCALAR = _Scalar()
ARRAY = _Array()


# ------------------------------------------------------------------ component algebra
# Operation order follows the numpy code these replaced (np.sum and np.linalg.norm add
# left to right), so results match it to rounding. The helpers the IK calls a dozen times
# a frame (rotate, place, aim, swing, two_bone) have their arithmetic written out rather
# than composed from the small ones: on floats a Python call costs about as much as a
# quaternion product's arithmetic (measured 0.15 of 0.5 µs).

def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    a0, a1, a2 = a
    b0, b1, b2 = b
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


def add(a, b):
    return a[0] + b[0], a[1] + b[1], a[2] + b[2]


def sub(a, b):
    return a[0] - b[0], a[1] - b[1], a[2] - b[2]


def scale(a, s):
    return a[0] * s, a[1] * s, a[2] * s


def unit(v, xp, fallback=None):
    """v / |v| (|v| floored at 1e-12); where |v| <= 1e-9, ``fallback`` if one is given."""
    x, y, z = v
    n = xp.sqrt(x * x + y * y + z * z)
    d = xp.maximum(n, 1e-12)
    if fallback is None:
        return x / d, y / d, z / d
    ok = n > 1e-9
    return xp.select(ok, x / d, fallback[0]), xp.select(ok, y / d, fallback[1]), xp.select(ok, z / d, fallback[2])


def qmul(a, b):
    """Hamilton product a * b (b first, then a)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def qmul_conj(a, b):
    """conj(a) * b: b relative to a (a unit)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx - ax * bw - ay * bz + az * by,
            aw * by + ax * bz - ay * bw - az * bx,
            aw * bz - ax * by + ay * bx - az * bw,
            aw * bw + ax * bx + ay * by + az * bz)


def rotate(q, v):
    """v rotated by the unit quaternion q: v + w t + u x t with t = 2 u x v."""
    x, y, z, w = q
    vx, vy, vz = v
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz), vz + w * tz + (x * ty - y * tx)


def place(p, q, v):
    """p + rotate(q, v): a joint from its parent's joint and rotation."""
    x, y, z, w = q
    vx, vy, vz = v
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (p[0] + (vx + w * tx + (y * tz - z * ty)), p[1] + (vy + w * ty + (z * tx - x * tz)),
            p[2] + (vz + w * tz + (x * ty - y * tx)))


def swing(a, b, xp):
    """The smallest rotation turning direction a onto b; half a turn about an axis
    perpendicular to a when they are opposite."""
    ax, ay, az = a
    bx, by, bz = b
    d = xp.maximum(xp.sqrt(ax * ax + ay * ay + az * az), 1e-12)
    ax, ay, az = ax / d, ay / d, az / d
    d = xp.maximum(xp.sqrt(bx * bx + by * by + bz * bz), 1e-12)
    bx, by, bz = bx / d, by / d, bz / d
    x, y, z = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    w = 1.0 + (ax * bx + ay * by + az * bz)
    if xp.any(w <= 1e-9):
        # a x X, or a x Y when a lies along X.
        p0 = xp.sqrt(az * az + ay * ay) > 1e-6
        px, py, pz = unit((xp.select(p0, 0.0, -az), xp.select(p0, az, 0.0), xp.select(p0, -ay, ax)), xp)
        ok = w > 1e-9
        x, y, z, w = xp.select(ok, x, px), xp.select(ok, y, py), xp.select(ok, z, pz), xp.select(ok, w, 0.0)
    n = xp.sqrt(x * x + y * y + z * z + w * w)
    return x / n, y / n, z / n, w / n


def aim(q, v, d, xp):
    """swing(rotate(q, v), d) * q: q turned the least so that its v points along d."""
    x, y, z, w = q
    vx, vy, vz = v
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    ax, ay, az = vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz), vz + w * tz + (x * ty - y * tx)
    # swing((ax, ay, az), d), written out but for the opposite-directions case
    bx, by, bz = d
    n = xp.maximum(xp.sqrt(ax * ax + ay * ay + az * az), 1e-12)
    ux, uy, uz = ax / n, ay / n, az / n
    n = xp.maximum(xp.sqrt(bx * bx + by * by + bz * bz), 1e-12)
    bx, by, bz = bx / n, by / n, bz / n
    sw = 1.0 + (ux * bx + uy * by + uz * bz)
    if xp.any(sw <= 1e-9):
        sx, sy, sz, sw = swing((ax, ay, az), d, xp)
    else:
        sx, sy, sz = uy * bz - uz * by, uz * bx - ux * bz, ux * by - uy * bx
        n = xp.sqrt(sx * sx + sy * sy + sz * sz + sw * sw)
        sx, sy, sz, sw = sx / n, sy / n, sz / n, sw / n
    return (sw * x + sx * w + sy * z - sz * y,
            sw * y - sx * z + sy * w + sz * x,
            sw * z + sx * y - sy * x + sz * w,
            sw * w - sx * x - sy * y - sz * z)


def frame(a, b, xp):
    """Orthonormal frame (a, b', a x b') as a 3x3 matrix, row-major, columns the axes."""
    a = unit(a, xp)
    b = unit(sub(b, scale(a, dot(a, b))), xp)
    c = cross(a, b)
    return (a[0], b[0], c[0], a[1], b[1], c[1], a[2], b[2], c[2])


def align(f0, a1, b1, xp):
    """The rotation taking the frame ``f0`` (from ``frame(a0, b0)``) onto frame(a1, b1):
    a0 onto a1 exactly, b0 as close to b1 as it can go."""
    f1 = frame(a1, b1, xp)
    # m = f1 @ f0^T
    m = tuple(f1[3 * i] * f0[3 * j] + f1[3 * i + 1] * f0[3 * j + 1] + f1[3 * i + 2] * f0[3 * j + 2]
              for i in range(3) for j in range(3))
    return xp.matrix_to_quat(m)


def two_bone(root, target, a, b, pole, hint, xp):
    """Middle joint of a two-bone chain of lengths a, b from ``root`` reaching towards
    ``target`` and bending towards ``pole`` (plus the vector ``hint``, which decides only
    when the pole is close to the reach line). Returns (joint, hinge axis)."""
    rx, ry, rz = root
    dx, dy, dz = target[0] - rx, target[1] - ry, target[2] - rz
    dist = xp.sqrt(dx * dx + dy * dy + dz * dz)
    n = xp.maximum(dist, 1e-12)
    ux, uy, uz = dx / n, dy / n, dz / n
    if xp.any(dist <= 1e-9):  # target on the root: reach down
        ok = dist > 1e-9
        ux, uy, uz = xp.select(ok, ux, 0.0), xp.select(ok, uy, -1.0), xp.select(ok, uz, 0.0)
    lo = abs(a - b) + 1e-4
    dist = xp.clip(dist, lo, xp.maximum(a + b - 1e-4, lo))
    cos_a = xp.clip((a * a + dist * dist - b * b) / xp.maximum(2 * a * dist, 1e-12), -1.0, 1.0)
    sin_a = xp.sqrt(1.0 - cos_a * cos_a)
    vx, vy, vz = pole[0] - rx, pole[1] - ry, pole[2] - rz
    if hint is not None:
        vx, vy, vz = vx + hint[0], vy + hint[1], vz + hint[2]
    k = vx * ux + vy * uy + vz * uz
    vx, vy, vz = vx - ux * k, vy - uy * k, vz - uz * k
    n = xp.sqrt(vx * vx + vy * vy + vz * vz)
    if xp.any(n <= 1e-9):  # pole on the reach line: bend towards any perpendicular
        fx, fy, fz = unit((0.0 * ux, uz, -uy), xp, (0.0, 0.0, 1.0))  # u x X
        ok = n > 1e-9
        vx, vy, vz = xp.select(ok, vx, fx), xp.select(ok, vy, fy), xp.select(ok, vz, fz)
        n = xp.sqrt(vx * vx + vy * vy + vz * vz)
    d = xp.maximum(n, 1e-12)
    vx, vy, vz = vx / d, vy / d, vz / d
    joint = (rx + (ux * cos_a + vx * sin_a) * a, ry + (uy * cos_a + vy * sin_a) * a,
             rz + (uz * cos_a + vz * sin_a) * a)
    return joint, (-(uy * vz - uz * vy), -(uz * vx - ux * vz), -(ux * vy - uy * vx))


def local_rotations(world, parents, prev=None):
    """Local rotations conj(world[parent]) * world[j] (the root's is its world rotation).
    With ``prev`` (the previous frame's, floats only), each is negated where that keeps
    it on the side of its predecessor: canonical_hemisphere's rule, in the same loop."""
    out = [world[0]]
    for j in range(1, len(world)):
        ax, ay, az, aw = world[parents[j]]
        bx, by, bz, bw = world[j]
        x, y, z, w = (aw * bx - ax * bw - ay * bz + az * by,
                      aw * by + ax * bz - ay * bw - az * bx,
                      aw * bz - ax * by + ay * bx - az * bw,
                      aw * bw + ax * bx + ay * by + az * bz)
        if prev is not None:
            p = prev[j]
            if x * p[0] + y * p[1] + z * p[2] + w * p[3] < 0.0:
                x, y, z, w = -x, -y, -z, -w
        out.append((x, y, z, w))
    if prev is not None:
        x, y, z, w = out[0]
        p = prev[0]
        if x * p[0] + y * p[1] + z * p[2] + w * p[3] < 0.0:
            out[0] = (-x, -y, -z, -w)
    return out


# ------------------------------------------------------------------ (..., 3) / (..., 4) arrays


def split(v: np.ndarray) -> tuple:
    v = np.asarray(v, np.float64)
    return tuple(v[..., i] for i in range(v.shape[-1]))


def join(c) -> np.ndarray:
    return np.stack(np.broadcast_arrays(*c), axis=-1)


def _unit(v: np.ndarray, fallback: np.ndarray | None = None) -> np.ndarray:
    return join(unit(split(v), ARRAY, None if fallback is None else split(fallback)))


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """np.cross for (..., 3), without its per-call overhead."""
    return join(cross(split(a), split(b)))


def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotations (..., 4) turning directions a onto b (..., 3)."""
    return join(swing(split(a), split(b), ARRAY))


def _align(a0: np.ndarray, b0: np.ndarray, a1: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """Rotations taking direction a0 onto a1 exactly and b0 as close to b1 as possible."""
    return join(align(frame(split(a0), split(b0), ARRAY), split(a1), split(b1), ARRAY))


def _two_bone(root, target, a, b, pole, hint=None):
    """``two_bone`` on (..., 3) arrays; a and b broadcast against them."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    if a.ndim:  # (..., 1) lengths next to (..., 3) vectors
        a, b = a[..., 0], b[..., 0]
    joint, hinge = two_bone(split(root), split(target), a, b, split(pole),
                            None if hint is None else split(hint), ARRAY)
    return join(joint), join(hinge)


# (q q^T).ravel() @ _QQ_MATRIX = |q|^2 times the rotation matrix of q (row-major), and the
# last column |q|^2: rotation without scipy's per-call Rotation construction (tens of µs).
_QQ_MATRIX = np.zeros((4, 4, 10))
for _o, _terms in enumerate((
        ((3, 3, 1), (0, 0, 1), (1, 1, -1), (2, 2, -1)), ((0, 1, 2), (3, 2, -2)), ((0, 2, 2), (3, 1, 2)),
        ((0, 1, 2), (3, 2, 2)), ((3, 3, 1), (0, 0, -1), (1, 1, 1), (2, 2, -1)), ((1, 2, 2), (3, 0, -2)),
        ((0, 2, 2), (3, 1, -2)), ((1, 2, 2), (3, 0, 2)), ((3, 3, 1), (0, 0, -1), (1, 1, -1), (2, 2, 1)),
        ((0, 0, 1), (1, 1, 1), (2, 2, 1), (3, 3, 1)))):
    for _i, _j, _c in _terms:
        _QQ_MATRIX[_i, _j, _o] = _c
_QQ_MATRIX = _QQ_MATRIX.reshape(16, 10)


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vectors (..., 3) rotated by quaternions (..., 4) (normalised here, as scipy's
    apply does), broadcasting; rotations.apply without scipy's overhead."""
    q = np.asarray(q, np.float64)
    v = np.asarray(v, np.float64)
    m = (q[..., :, None] * q[..., None, :]).reshape(*q.shape[:-1], 16) @ _QQ_MATRIX
    r = (m[..., :9].reshape(*m.shape[:-1], 3, 3) @ v[..., None])[..., 0]
    return r / m[..., 9:]


def _qmean(q: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Mean rotation of q (N, 4) (sign-aligned, normalised average: fine for a cluster)."""
    q = np.asarray(q, float)
    q = q * np.where(np.sum(q * q[:1], axis=-1, keepdims=True) < 0, -1.0, 1.0)
    w = np.ones(len(q)) if weights is None else np.asarray(weights, float)
    m = (q * w[:, None]).sum(0)
    n = np.linalg.norm(m)
    return rot.IDENTITY.copy() if n < 1e-12 else m / n


