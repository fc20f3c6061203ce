"""How a motion word is shown to the networks: one interface, two representations.

A motion word is 60 frames of the 22 humanoid bones' local rotations (T-pose relative,
quaternions x, y, z, w; see ``stylecast.motion.humanoid``). ``Representation.encode``
turns quaternions (..., J, 4) into features (..., J, C); ``decode`` goes back.

* ``euler`` (the paper's): intrinsic X-Z-Y Euler angles (R = Rx @ Rz @ Ry, written "XZY"
  as in ``stylecast.motion.rotations``), each angle wrapped to [-180, 180] degrees and
  scaled by the FIXED factor 1/180 to [-1, 1]. C = 3.
* ``6d``: the first two columns of the rotation matrix (Zhou et al. 2019), continuous
  everywhere; decode re-orthonormalises by Gram-Schmidt. C = 6.

Normalisation (stored in the checkpoint): the scale is fixed, angle / 180, so no data-
dependent min-max is needed and every dataset shares one scale. Optionally a per-bone
reference rotation ``ref`` centres the data first (d = q * ref^-1, before any Euler
angle); the shipped models do NOT use it (reference None = exactly T-pose relative, the
paper's). It was needed while the humanoid mapping left constant twists near 180 degrees
in some bones (retarget version 1) and stays available for rigs that do.

Why XZY: measured on the training words of normal and exhausted (retarget version 2,
T-pose relative), XZY had 0.001 % of bone-frames with the middle angle beyond 75 degrees
(gimbal lock) and no +-180 degree wrap inside any word; ZXY (the BVH channel order, and
Unity's axis order) had 0.15 % near gimbal lock and wrap jumps in 1.6 % of LeftLowerLeg
frames (deep knee bends pass the middle angle's +-90 degree limit).

Heading: the Hips rotation carries the performer's facing, which is arbitrary (and wraps
at +-180 degrees for a performer walking towards -Z). ``remove_heading`` turns every
word about the vertical so the Hips face +Z at the word's centre frame and returns the
yaw; ``restore_heading`` puts it back. Style lives in how a body moves, not in where it
faces, so the networks see heading-free words.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from stylecast.motion import rotations as rot

EULER_ORDER = "XZY"
EULER_SCALE_DEG = 180.0


class Representation:
    """Quaternions (..., J, 4) <-> features (..., J, C); vectorised over leading axes."""

    name: str = ""
    channels: int = 0

    def __init__(self, reference: np.ndarray | None = None):
        self.reference = None if reference is None else np.asarray(reference, dtype=np.float64)

    def centre(self, quats: np.ndarray) -> np.ndarray:
        q = np.asarray(quats, dtype=np.float64)
        if self.reference is None:
            return q
        if q.shape[-2] != len(self.reference):
            raise ValueError(f"expected {len(self.reference)} bones, got {q.shape[-2]}")
        return rot.multiply(q, rot.inverse(self.reference))

    def uncentre(self, quats: np.ndarray) -> np.ndarray:
        return quats if self.reference is None else rot.multiply(quats, self.reference)

    def encode(self, quats: np.ndarray) -> np.ndarray:
        return self._encode(self.centre(quats))

    def decode(self, features: np.ndarray) -> np.ndarray:
        return self.uncentre(self._decode(features))

    def _encode(self, quats: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _decode(self, features: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def reference_metadata(self) -> list | None:
        return None if self.reference is None else np.round(self.reference, 9).tolist()

    def combine(self, x, delta):
        """Generator output = input word corrected by ``delta`` (torch tensors)."""
        raise NotImplementedError

    def metadata(self) -> dict:
        raise NotImplementedError


def _atanh(x):
    """torch.atanh in training (the shipped weights were trained with it and retrain bit
    for bit); for inference the same function through log1p, because torch.atanh rounds
    an element differently with the size of the tensor it is in (a word alone against a
    word in a batch), while log1p does not: a live restyler's words must not depend on
    their batch (``networks.INFERENCE_FORMS``)."""
    import torch

    if torch.is_grad_enabled():
        return torch.atanh(x)
    return 0.5 * (torch.log1p(x) - torch.log1p(-x))


def xzy_to_quat(angles_deg: np.ndarray) -> np.ndarray:
    """Intrinsic XZY Euler angles (..., 3) in degrees -> quaternions (..., 4) xyzw.

    The same as ``rotations.from_euler(a, "XZY")`` (tests check it against scipy) but
    ~20x faster: it is on the per-word path of the live restyler, where scipy's generic
    Euler code costs more than the generator itself."""
    h = np.radians(np.asarray(angles_deg, dtype=np.float64)) * 0.5
    sx, sz, sy = np.sin(h[..., 0]), np.sin(h[..., 1]), np.sin(h[..., 2])
    cx, cz, cy = np.cos(h[..., 0]), np.cos(h[..., 1]), np.cos(h[..., 2])
    # (qx * qz) * qy written out, R = Rx @ Rz @ Ry; qx * qz = (sx cz, -sx sz, cx sz, cx cz).
    mx, my, mz, mw = sx * cz, -sx * sz, cx * sz, cx * cz
    out = np.empty((*h.shape[:-1], 4))
    out[..., 0] = mx * cy - mz * sy
    out[..., 1] = mw * sy + my * cy
    out[..., 2] = mx * sy + mz * cy
    out[..., 3] = mw * cy - my * sy
    return out


def quat_to_xzy(q: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) -> intrinsic XZY Euler angles (..., 3) in degrees, the first
    and last in (-180, 180], the middle in [-90, 90]; at gimbal lock the last is zero
    (as scipy does). Checked against ``rotations.to_euler(q, "XZY")`` in the tests."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    # The rotation matrix entries that R = Rx(a) Rz(b) Ry(c) needs:
    r00 = 1 - 2 * (y * y + z * z)
    r01 = 2 * (x * y - z * w)
    r02 = 2 * (x * z + y * w)
    r11 = 1 - 2 * (x * x + z * z)
    r12 = 2 * (y * z - x * w)
    r21 = 2 * (y * z + x * w)
    r22 = 1 - 2 * (x * x + y * y)
    b = np.arcsin(np.clip(-r01, -1.0, 1.0))  # R01 = -sin b
    locked = np.abs(r01) > 1 - 1e-9
    a = np.where(locked, np.arctan2(-r12, r22), np.arctan2(r21, r11))  # R21 = sa cb, R11 = ca cb
    c = np.where(locked, 0.0, np.arctan2(r02, r00))  # R02 = cb sc, R00 = cb cc
    return np.degrees(np.stack([a, b, c], axis=-1))


class EulerRepresentation(Representation):
    name = "euler"
    channels = 3

    def _encode(self, quats: np.ndarray) -> np.ndarray:
        # Angles come back in [-180, 180]: the wrap of the paper.
        return (quat_to_xzy(quats) / EULER_SCALE_DEG).astype(np.float32)

    def _decode(self, features: np.ndarray) -> np.ndarray:
        return xzy_to_quat(np.asarray(features, dtype=np.float64) * EULER_SCALE_DEG)

    def combine(self, x, delta):
        # A residual in atanh space: identity when delta = 0, always inside (-1, 1)
        # (the paper's tanh output), smooth, and the correction shrinks near the +-180
        # degree wrap where a jump would be the only way out.
        import torch

        return torch.tanh(_atanh(x.clamp(-0.999, 0.999)) + delta)

    def metadata(self) -> dict:
        return {"name": self.name, "channels": self.channels, "euler_order": EULER_ORDER,
                "euler_convention": "intrinsic, R = Rx @ Rz @ Ry, degrees wrapped to [-180, 180]",
                "normalisation": {"kind": "fixed", "scale_deg": EULER_SCALE_DEG,
                                  "centring": "d = q * reference^-1 per bone, before the Euler angles"},
                "reference": self.reference_metadata()}


class SixDRepresentation(Representation):
    name = "6d"
    channels = 6

    def _encode(self, quats: np.ndarray) -> np.ndarray:
        q = np.asarray(quats, dtype=np.float64)
        m = Rotation.from_quat(q.reshape(-1, 4)).as_matrix()  # (N, 3, 3)
        six = np.concatenate([m[:, :, 0], m[:, :, 1]], axis=-1)
        return six.reshape(*q.shape[:-1], 6).astype(np.float32)

    def _decode(self, features: np.ndarray) -> np.ndarray:
        f = np.asarray(features, dtype=np.float64)
        flat = f.reshape(-1, 6)
        a, b = flat[:, :3], flat[:, 3:]
        x = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-8)
        b = b - np.sum(x * b, axis=-1, keepdims=True) * x
        y = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-8)
        z = np.cross(x, y)
        m = np.stack([x, y, z], axis=-1)  # columns
        return Rotation.from_matrix(m).as_quat().reshape(*f.shape[:-1], 4)

    def combine(self, x, delta):
        return x + delta  # decode re-orthonormalises; no range to protect

    def metadata(self) -> dict:
        return {"name": self.name, "channels": self.channels,
                "normalisation": {"kind": "none", "note": "rotation-matrix columns already lie in [-1, 1]",
                                  "centring": "d = q * reference^-1 per bone, before the matrix columns"},
                "reference": self.reference_metadata()}


REPRESENTATIONS = {"euler": EulerRepresentation, "6d": SixDRepresentation}


def get_representation(name: str, reference: np.ndarray | None = None) -> Representation:
    from stylecast.motion.errors import UserError

    try:
        return REPRESENTATIONS[name](reference)
    except KeyError:
        raise UserError(f"unknown representation {name!r}; choose one of {', '.join(REPRESENTATIONS)}") from None


def mean_reference(words: np.ndarray, stride: int = 5) -> np.ndarray:
    """Per-bone chordal mean rotation (J, 4) of quaternion words (N, T, J, 4)."""
    w = np.asarray(words, dtype=np.float64)[:, ::stride]
    J = w.shape[-2]
    return np.stack([Rotation.from_quat(w[..., j, :].reshape(-1, 4)).mean().as_quat() for j in range(J)])


def euler_features(quats: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray:
    """Normalised Euler angles (the paper's units) of quaternions, centred on ``reference``:
    the metrics of METHOD.md are measured in these, whatever representation a model uses."""
    return EulerRepresentation(reference).encode(quats)


# --- heading -----------------------------------------------------------------------

def word_heading(words: np.ndarray, hips: int = 0) -> np.ndarray:
    """Yaw (radians, about +Y) of the Hips' forward axis at each word's centre frame.

    words: (B, T, J, 4) -> (B,). The rotated +Z axis is the rotation matrix's third
    column, written homogeneously (scaled by |q|^2, which atan2 ignores); the torch path
    (``representation_torch.word_heading``) uses the same expression, so both give the
    same bits."""
    x, y, z, w = np.moveaxis(np.asarray(words)[:, words.shape[1] // 2, hips], -1, 0)
    return np.arctan2(2.0 * (x * z + y * w), w * w + z * z - x * x - y * y)


def _yaw_quats(yaw: np.ndarray) -> np.ndarray:
    half = 0.5 * np.asarray(yaw, dtype=np.float64)
    return np.stack([np.zeros_like(half), np.sin(half), np.zeros_like(half), np.cos(half)], axis=-1)


def remove_heading(words: np.ndarray, hips: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Turn each word (B, T, J, 4) so its Hips face +Z at the centre frame; returns the
    turned words and the yaw that ``restore_heading`` needs."""
    yaw = word_heading(words, hips)
    out = np.array(words, dtype=np.float64, copy=True)
    inv = _yaw_quats(-yaw)[:, None, :]  # (B, 1, 4) broadcast over frames
    out[:, :, hips] = rot.multiply(inv, out[:, :, hips])
    return out, yaw


def restore_heading(words: np.ndarray, yaw: np.ndarray, hips: int = 0) -> np.ndarray:
    out = np.array(words, dtype=np.float64, copy=True)
    out[:, :, hips] = rot.multiply(_yaw_quats(yaw)[:, None, :], out[:, :, hips])
    return out
