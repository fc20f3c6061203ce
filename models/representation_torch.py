"""The representation in torch: the same maths as ``representation`` (the numpy
reference), on whatever device the model lives on.

``Restyler.restyle_words`` runs a whole batch of quaternion words through heading
removal, encoding, the generator, decoding, heading restoration and the hemisphere fix
without leaving the device: on a GPU the numpy version of this work (per word, on the
host) cost more than the generator itself (issue 12).

Precision: every step on quaternions, angles and matrices runs in float64, as the numpy
reference does; features are rounded to float32 exactly where the numpy code rounds
them (the generator's input), so both paths feed the generator the same numbers.
tests/test_representation_torch.py checks the two paths agree within 1e-5 degrees on
real Bandai clips, for both representations.

Quaternions are (x, y, z, w), as everywhere in stylecast (``motion.rotations``).
"""

from __future__ import annotations

import numpy as np
import torch

from stylecast.motion import rotations as rot

from . import representation as R

DTYPE = torch.float64  # the numpy reference's precision; see the module docstring


def components(q: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """The last axis as separate contiguous tensors: elementwise work on the strided views
    ``unbind(-1)`` gives ran at half speed on the CPU."""
    return q.movedim(-1, 0).contiguous().unbind(0)


def multiply(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Hamilton product a * b (apply b first), broadcasting leading shapes."""
    ax, ay, az, aw = a.unbind(-1)
    bx, by, bz, bw = b.unbind(-1)
    return torch.stack([aw * bx + ax * bw + ay * bz - az * by,
                        aw * by - ax * bz + ay * bw + az * bx,
                        aw * bz + ax * by - ay * bx + az * bw,
                        aw * bw - ax * bx - ay * by - az * bz], dim=-1)


def inverse(q: torch.Tensor) -> torch.Tensor:
    conj = q * q.new_tensor([-1.0, -1.0, -1.0, 1.0])
    return conj / (q * q).sum(-1, keepdim=True)


# -- heading ---------------------------------------------------------------------------

def word_heading(words: torch.Tensor, hips: int = 0) -> torch.Tensor:
    """Yaw (radians about +Y) of the Hips' forward axis at each word's centre frame, (B,).

    The rotated +Z axis is the rotation matrix's third column; written homogeneously
    (scaled by |q|^2), which leaves atan2 unchanged, so no normalisation is needed."""
    x, y, z, w = words[:, words.shape[1] // 2, hips].unbind(-1)
    return torch.atan2(2.0 * (x * z + y * w), w * w + z * z - x * x - y * y)


def yaw_quats(yaw: torch.Tensor) -> torch.Tensor:
    half = 0.5 * yaw
    zero = torch.zeros_like(half)
    return torch.stack([zero, torch.sin(half), zero, torch.cos(half)], dim=-1)


def remove_heading(words: torch.Tensor, hips: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """Turn each word (B, T, J, 4) so its Hips face +Z at the centre frame; returns the
    turned words and the yaw for ``restore_heading``."""
    yaw = word_heading(words, hips)
    out = words.clone()
    out[:, :, hips] = multiply(yaw_quats(-yaw)[:, None, :], words[:, :, hips])
    return out, yaw


def restore_heading(words: torch.Tensor, yaw: torch.Tensor, hips: int = 0) -> torch.Tensor:
    out = words.clone()
    out[:, :, hips] = multiply(yaw_quats(yaw)[:, None, :], words[:, :, hips])
    return out


def same_hemisphere(out: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
    """``out`` with each quaternion's sign chosen to have a non-negative dot with ``like``
    (q and -q are one rotation; the blender interpolates between input and output)."""
    dot = (out * like) @ out.new_ones(4)  # cheaper than a sum over a length-4 axis
    return out * torch.where(dot < 0, -1.0, 1.0).unsqueeze(-1)


def continuous_in_time(q: torch.Tensor) -> torch.Tensor:
    """Words (B, T, J, 4) with signs flipped along T so consecutive quaternions have a
    non-negative dot: ``motion.rotations.canonical_hemisphere(q, axis=1)``, the same
    products in the same order, so the same bits."""
    a, b = q[:, 1:], q[:, :-1]
    dots = a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2] + a[..., 3] * b[..., 3]
    flips = torch.cumprod(torch.where(dots < 0, -1.0, 1.0), dim=1)
    return torch.cat([q[:, :1], a * flips.unsqueeze(-1)], dim=1)


def usable_words(words: torch.Tensor) -> torch.Tensor:
    """(B, T, J, 4) -> (B,) bool: ``motion.rotations.usable_words``."""
    finite = torch.isfinite(words).flatten(1).all(1)
    return finite & (torch.linalg.vector_norm(words, dim=-1) > rot.MIN_QUATERNION_NORM).flatten(1).all(1)


# -- Euler XZY ---------------------------------------------------------------------------

def quat_to_xzy(q: torch.Tensor) -> torch.Tensor:
    """Quaternions (..., 4) -> intrinsic XZY angles (..., 3) in degrees (see the numpy
    ``representation.quat_to_xzy`` for the derivation and the gimbal-lock rule)."""
    x, y, z, w = components(q)
    norm = torch.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    r00 = 1 - 2 * (y * y + z * z)
    r01 = 2 * (x * y - z * w)
    r02 = 2 * (x * z + y * w)
    r11 = 1 - 2 * (x * x + z * z)
    r21 = 2 * (y * z + x * w)
    b = torch.asin(torch.clamp(-r01, -1.0, 1.0))
    a = torch.atan2(r21, r11)
    c = torch.atan2(r02, r00)
    # Gimbal lock: computed everywhere and chosen where it happens, never branched on in
    # Python (the restyle runs as a traced graph, ``pipeline``, which has no branches).
    locked = r01.abs() > 1 - 1e-9
    r12 = 2 * (y * z - x * w)
    r22 = 1 - 2 * (x * x + y * y)
    a = torch.where(locked, torch.atan2(-r12, r22), a)
    c = torch.where(locked, torch.zeros_like(c), c)
    return torch.stack([a, b, c], dim=-1) * (180.0 / torch.pi)


def xzy_to_quat(angles_deg: torch.Tensor) -> torch.Tensor:
    h = components(torch.deg2rad(angles_deg) * 0.5)
    sx, sz, sy = (torch.sin(v) for v in h)
    cx, cz, cy = (torch.cos(v) for v in h)
    mx, my, mz, mw = sx * cz, -sx * sz, cx * sz, cx * cz  # qx * qz
    return torch.stack([mx * cy - mz * sy, mw * sy + my * cy, mx * sy + mz * cy, mw * cy - my * sy], dim=-1)


# -- rotation matrices (6D) ----------------------------------------------------------------

def quat_to_matrix(q: torch.Tensor) -> torch.Tensor:
    q = q / torch.linalg.vector_norm(q, dim=-1, keepdim=True)
    x, y, z, w = q.unbind(-1)
    rows = [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
            2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
            2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]
    return torch.stack(rows, dim=-1).reshape(*q.shape[:-1], 3, 3)


def matrix_to_quat(m: torch.Tensor) -> torch.Tensor:
    """Rotation matrices (..., 3, 3) -> unit quaternions, by the branch with the largest
    of (trace, diagonal) for accuracy (Shepperd's method, as scipy's from_matrix). The
    sign may differ from scipy's; callers fix the hemisphere."""
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    trace = m00 + m11 + m22
    candidates = torch.stack([  # each row proportional to (x, y, z, w)
        torch.stack([1 + 2 * m00 - trace, m01 + m10, m02 + m20, m21 - m12], -1),
        torch.stack([m01 + m10, 1 + 2 * m11 - trace, m12 + m21, m02 - m20], -1),
        torch.stack([m02 + m20, m12 + m21, 1 + 2 * m22 - trace, m10 - m01], -1),
        torch.stack([m21 - m12, m02 - m20, m10 - m01, 1 + trace], -1)], dim=-2)
    choice = torch.stack([m00, m11, m22, trace], -1).argmax(-1)
    q = torch.gather(candidates, -2, choice[..., None, None].expand(*choice.shape, 1, 4))[..., 0, :]
    return q / torch.linalg.vector_norm(q, dim=-1, keepdim=True)


def six_d_to_matrix(f: torch.Tensor) -> torch.Tensor:
    """Two columns (..., 6) -> rotation matrices by Gram-Schmidt (the numpy reference's)."""
    a, b = f[..., :3], f[..., 3:]
    x = a / torch.clamp(torch.linalg.vector_norm(a, dim=-1, keepdim=True), min=1e-8)
    b = b - (x * b).sum(-1, keepdim=True) * x
    y = b / torch.clamp(torch.linalg.vector_norm(b, dim=-1, keepdim=True), min=1e-8)
    z = torch.linalg.cross(x, y, dim=-1)
    return torch.stack([x, y, z], dim=-1)  # columns


# -- representations -------------------------------------------------------------------------

def _euler_encode(q: torch.Tensor) -> torch.Tensor:
    return quat_to_xzy(q) / R.EULER_SCALE_DEG


def _euler_decode(f: torch.Tensor) -> torch.Tensor:
    return xzy_to_quat(f * R.EULER_SCALE_DEG)


def _six_d_encode(q: torch.Tensor) -> torch.Tensor:
    m = quat_to_matrix(q)
    return torch.cat([m[..., :, 0], m[..., :, 1]], dim=-1)


def _six_d_decode(f: torch.Tensor) -> torch.Tensor:
    return matrix_to_quat(six_d_to_matrix(f))


# name -> (encode: float64 quaternions -> float64 features, decode: the reverse)
CODECS = {"euler": (_euler_encode, _euler_decode), "6d": (_six_d_encode, _six_d_decode)}


class TorchRepresentation:
    """A numpy ``Representation`` (its name and reference pose) as torch functions on
    ``device``: encode (..., J, 4) float64 -> (..., J, C) float32, decode back."""

    def __init__(self, rep: R.Representation, device: torch.device | str = "cpu"):
        if rep.name not in CODECS:
            raise ValueError(f"no torch version of the representation {rep.name!r}")
        self.name = rep.name
        self.channels = rep.channels
        self._encode, self._decode = CODECS[rep.name]
        self.device = torch.device(device)
        ref = None if rep.reference is None else np.asarray(rep.reference, np.float64)
        self.reference = None if ref is None else torch.as_tensor(ref, dtype=DTYPE, device=self.device)
        self.reference_inverse = None if ref is None else inverse(self.reference)

    def encode(self, quats: torch.Tensor) -> torch.Tensor:
        q = quats if self.reference is None else multiply(quats, self.reference_inverse)
        return self._encode(q).to(torch.float32)  # where the numpy reference rounds too

    def decode(self, features: torch.Tensor) -> torch.Tensor:
        q = self._decode(features.to(DTYPE))
        return q if self.reference is None else multiply(q, self.reference)
