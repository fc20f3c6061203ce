"""Tracker poses -> humanoid pose frames: calibration, hold-and-blend, analytic IK.

Space and units are those of ``motion.rotations`` (right-handed, Y up, facing +Z, cm,
quaternions x, y, z, w). Output rotations are local rotations of the canonical humanoid
(``HUMANOID_BONES``), relative to the calibrated skeleton's T-pose frames; the root
position is the Hips joint's world position (as in ``Retarget.to_humanoid``).

The pipeline of one frame (``TrackerSolver.solve``, or ``solve_batch`` for many at once):

1. **Tracker -> bone.** Each tracker is rigidly strapped to a bone; calibration measured
   the strap (``mount_positions``/``mount_rotations``, in the bone's frame), so a tracker
   pose gives its bone's world rotation and joint position directly.
2. **Hold and blend** (``_HoldBlend``). A lost tracker's bone keeps its last pose
   relative to the hips (the waist itself is placed from the thigh trackers, else follows
   the headset's translation, else freezes); when the tracker comes back the output moves
   from the held pose to the live one over ``blend_time`` seconds (smoothstep), so neither
   loss nor return ever jumps.
3. **IK** (``_solve_core``), vectorised over frames:
   * Hips: the waist tracker. Head: the headset.
   * Spine (Spine, Chest, UpperChest, Neck): the rotation from the hips to the head,
     beyond the performer's neutral posture, is shared out along the chain
     (``SPINE_WEIGHTS``), the chain is turned about its base to point at the head joint,
     and the neck finally aims at it.
   * Arms and legs, all four at once: two-bone IK from the shoulder socket / hip joint to
     the wrist / ankle (from the hand / foot tracker). With 10 points the elbow / knee
     tracker is the pole target and gives the upper bone's twist, and its socket estimate
     aims the clavicle. With 6 points an elbow is sought back along the forearm from the
     wrist (the forearm's direction in the hand frame is learned at calibration), a knee
     where it pointed at calibration in the hips frame; the twist comes from the learned
     hinge axis. A weak hint towards the usual bend direction keeps the bend plane
     defined for straight limbs and strong while the hand / foot is held.
   * Hands and feet take their trackers' rotations; toes keep their neutral rotation.

Calibration (``calibrate_known_pose``, ``calibrate_tpose``) learns the tracker straps,
the performer's bone lengths, their neutral posture (local rotations of untracked bones),
the hinge axes and the default poles.

Throughput: ``solve_batch`` is vectorised over frames (bench/bench_solver.py measures
it); ``solve`` runs the same code on one frame, which costs numpy's per-call overhead
(about a millisecond): ample for live rates, far from batch throughput. Hold and blend is
vectorised over each stretch of a lost or returning tracker.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from stylecast.motion import rotations as rot
from stylecast.motion.clip import Clip, PoseFrame
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import HUMANOID_BONES, HUMANOID_PARENTS, humanoid_skeleton_default
from stylecast.motion.skeleton import Skeleton

from .sources import Source
from .trackers import (ALL_ROLES, MOUNT_CHILD, NOMINAL_MOUNTS, TEN_POINT, TrackerPoses, TrackerRole,
                       nominal_mount)

B = {name: i for i, name in enumerate(HUMANOID_BONES)}
R = TrackerRole
N_ROLES = len(ALL_ROLES)
SPINE = ("Spine", "Chest", "UpperChest", "Neck")
# Cumulative share of the hips->head rotation (beyond neutral) carried by each spine bone's
# world frame; the head carries the rest.
SPINE_WEIGHTS = (0.35, 0.65, 0.8, 0.9)
DEFAULT_BLEND_TIME = 0.3  # seconds from a held pose back to the live one
POLE_HINT_CM = 1.5  # weight of the usual elbow / knee direction next to the pole target
HELD_POLE_HINT_CM = 40.0  # ... added while the hand / foot is held


@dataclass(frozen=True)
class _Limb:
    root: str  # Shoulder (clavicle) for arms, None for legs
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


# ------------------------------------------------------------------ vectorised helpers

def _norm(v: np.ndarray) -> np.ndarray:
    return np.linalg.norm(v, axis=-1, keepdims=True)


def _unit(v: np.ndarray, fallback: np.ndarray | None = None) -> np.ndarray:
    n = _norm(v)
    out = v / np.maximum(n, 1e-12)
    if fallback is not None:
        out = np.where(n > 1e-9, out, fallback)
    return out


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """np.cross for (..., 3), without its per-call overhead (it dominates one-frame solves)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotations (..., 4) turning directions a onto b (..., 3)."""
    a, b = _unit(a), _unit(b)
    w = 1.0 + np.sum(a * b, axis=-1, keepdims=True)
    q = np.concatenate([_cross(a, b), w], axis=-1)
    if np.any(w <= 1e-9):  # opposite vectors: half a turn about an axis perpendicular to a
        a = np.broadcast_to(a, q[..., :3].shape)
        perp = _cross(a, np.broadcast_to([1.0, 0.0, 0.0], a.shape))
        perp = np.where(_norm(perp) > 1e-6, perp, _cross(a, np.broadcast_to([0.0, 1.0, 0.0], a.shape)))
        q = np.where(w > 1e-9, q, np.concatenate([_unit(perp), np.zeros_like(w)], axis=-1))
    return q / _norm(q)


def _align(a0: np.ndarray, b0: np.ndarray, a1: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """Rotations taking direction a0 onto a1 exactly and b0 as close to b1 as possible."""
    def frame(a, b):
        a = _unit(a)
        b = _unit(b - np.sum(a * b, axis=-1, keepdims=True) * a)
        return np.stack([a, b, _cross(a, b)], axis=-1)
    m0, m1 = np.broadcast_arrays(frame(a0, b0), frame(a1, b1))
    m = m1 @ np.swapaxes(m0, -1, -2)
    shape = m.shape[:-2]
    return Rotation.from_matrix(m.reshape(-1, 3, 3)).as_quat().reshape(*shape, 4)


def _qmean(q: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Mean rotation of q (N, 4) (sign-aligned, normalised average: fine for a cluster)."""
    q = np.asarray(q, float)
    q = q * np.where(np.sum(q * q[:1], axis=-1, keepdims=True) < 0, -1.0, 1.0)
    w = np.ones(len(q)) if weights is None else np.asarray(weights, float)
    m = (q * w[:, None]).sum(0)
    n = np.linalg.norm(m)
    return rot.IDENTITY.copy() if n < 1e-12 else m / n


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


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


# ------------------------------------------------------------------ calibration


@dataclass(frozen=True, eq=False)
class Calibration:
    """What the solver knows about one performer and their straps.

    Arrays indexed by ``TrackerRole`` have a row for every role; rows of roles not in
    ``roles`` are unused.
    """

    skeleton: Skeleton  # humanoid, the performer's bone lengths
    roles: tuple[TrackerRole, ...]
    mount_positions: np.ndarray  # (10, 3) tracker position in its bone's frame, cm
    mount_rotations: np.ndarray  # (10, 4) tracker rotation relative to its bone
    neutral: np.ndarray  # (22, 4) neutral local rotations (posture of untracked bones)
    hinges: np.ndarray  # (4, 3) per LIMBS: elbow / knee hinge axis in the upper bone's frame
    end_directions: np.ndarray  # (4, 3) per LIMBS: lower-bone direction (elbow->wrist) in the end bone's frame
    rest_relative: np.ndarray  # (10, 7) each role's bone pose relative to the hips (p, q): first-frame fallback
    pole_directions: np.ndarray  # (4, 3) per LIMBS: where the elbow / knee points, in the limb root's parent frame
    method: str = "known-pose"

    @property
    def points(self) -> int:
        return len(self.roles)

    def has(self, role: TrackerRole) -> bool:
        return role in self.roles


def _chain(bone: int) -> list[int]:
    """Bones from the first below Hips down to ``bone`` (whose offsets place its joint)."""
    out = []
    while bone > 0:
        out.append(bone)
        bone = HUMANOID_PARENTS[bone]
    return out[::-1]


def _as_arrays(frames) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """TrackerPoses list or a (timestamps, positions, orientations, valid) tuple -> arrays."""
    if isinstance(frames, tuple):
        ts, p, q, v = frames
        return (np.asarray(ts, float), np.asarray(p, float), np.asarray(q, float), np.asarray(v, bool))
    frames = list(frames)
    return (np.array([f.timestamp for f in frames], float), np.stack([f.positions for f in frames]),
            np.stack([f.orientations for f in frames]), np.stack([f.valid for f in frames]))


def calibrate_known_pose(frames, motion: Clip, roles: tuple[TrackerRole, ...] = TEN_POINT, *,
                         learn_proportions: bool = True, length_prior_weight: float = 0.01) -> Calibration:
    """Calibrate from frames during which the performer's humanoid pose is known.

    ``frames``: TrackerPoses (or arrays) for T instants; ``motion``: a humanoid Clip of
    the same T frames (local rotations and root positions in the trackers' world space).
    ``motion.skeleton`` gives each bone's direction in the T-pose frames and, with
    ``learn_proportions``, only a weak prior on its length: the lengths and the strap
    offsets are solved together by ridge-regularised least squares on every tracker
    position (linear, because the rotations are known). The more the pose varies, the
    better determined the lengths; bones no tracker chain constrains (toes, an absent
    UpperChest) get the overall scale.
    """
    ts, P, Q, V = _as_arrays(frames)
    T = len(ts)
    if motion.num_frames != T or tuple(motion.skeleton.names) != HUMANOID_BONES:
        raise ValueError("calibration needs a humanoid clip with one frame per tracker frame")
    roles = tuple(sorted(set(roles)))
    for role in roles:
        if not V[:, role].any():
            raise UserError(f"calibration saw no valid pose from the {role.name} tracker; check that it "
                            f"is switched on and tracked, then calibrate again")
    world = _local_to_world(motion.rotations)  # (T, 22, 4)
    mats = Rotation.from_quat(world.reshape(-1, 4)).as_matrix().reshape(T, len(HUMANOID_BONES), 3, 3)
    offsets = np.array(motion.skeleton.offsets, float)
    if learn_proportions:
        offsets = _learn_lengths(P, V, mats, motion.root_positions, offsets, roles, length_prior_weight)
    skeleton = motion.skeleton.with_offsets(offsets)
    pos = _fk_positions(world, motion.root_positions, offsets)
    mount_p = np.zeros((N_ROLES, 3))
    mount_q = np.tile(rot.IDENTITY, (N_ROLES, 1))
    for role in roles:
        b, ok = B[role.bone], V[:, role]
        inv = rot.inverse(world[ok, b])
        mount_p[role] = rot.apply(inv, P[ok, role] - pos[ok, b]).mean(0)
        mount_q[role] = _qmean(rot.multiply(inv, Q[ok, role]))
    neutral = np.stack([_qmean(motion.rotations[:, j]) for j in range(len(HUMANOID_BONES))])
    hinges, ends = _limb_geometry(world, pos)
    rest_rel = _rest_relative(world, pos, roles)
    poles = _pole_directions(world, pos)
    return Calibration(skeleton, roles, mount_p, mount_q, neutral, hinges, ends, rest_rel, poles, "known-pose")


def _learn_lengths(P, V, mats, root, offsets, roles, prior_weight) -> np.ndarray:
    """Bone lengths (along the prior's directions) and strap offsets by least squares.

    Two passes: first one overall scale of the prior skeleton (well determined: it is the
    performer's size), then each length with a ridge towards the scaled prior (weakly
    determined when the pose barely varies, because a strap offset can absorb a length
    along a bone that keeps its direction). Bones no tracker chain constrains (toes, an
    absent UpperChest) get the overall scale.
    """
    T = len(P)
    lengths = np.linalg.norm(offsets, axis=1)
    dirs = offsets / np.maximum(lengths, 1e-12)[:, None]
    learn = sorted({j for role in roles for j in _chain(B[role.bone]) if lengths[j] > 1e-6})
    n_mount = 3 * len(roles)
    # Design: rows (tracker, frame, axis); columns: the learned lengths, then the straps.
    blocks, ys = [], []
    for k, role in enumerate(roles):
        b = B[role.bone]
        ok = V[:, role]
        rows = np.zeros((int(ok.sum()), 3, len(learn) + n_mount))
        for i, j in enumerate(learn):
            if j in _chain(b):
                rows[:, :, i] = mats[ok, HUMANOID_PARENTS[j]] @ dirs[j]
        rows[:, :, len(learn) + 3 * k: len(learn) + 3 * k + 3] = mats[ok, b]
        blocks.append(rows.reshape(-1, rows.shape[-1]))
        ys.append((P[ok, role] - root[ok]).reshape(-1))
    a, y = np.concatenate(blocks), np.concatenate(ys)
    prior = lengths[learn]
    # Pass 1: one scale for the whole prior skeleton.
    a1 = np.concatenate([a[:, :len(learn)] @ prior[:, None], a[:, len(learn):]], axis=1)
    reg1 = np.r_[0.0, np.full(n_mount, 1e-4 * T)]
    x1 = np.linalg.solve(a1.T @ a1 + np.diag(reg1), a1.T @ y)
    scale = float(np.clip(x1[0], 0.5, 2.0))
    # Pass 2: every length, pulled towards the scaled prior.
    reg = np.r_[np.full(len(learn), prior_weight * T), np.full(n_mount, 1e-4 * T)]
    target = np.r_[scale * prior, np.zeros(n_mount)]
    x = np.linalg.solve(a.T @ a + np.diag(reg), a.T @ y + reg * target)
    out = offsets * scale
    for i, j in enumerate(learn):
        out[j] = dirs[j] * max(x[i], 0.0)
    return out


def _limb_geometry(world: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hinge axes (in upper-bone frames) and lower-bone directions (in end-bone frames)."""
    hinges, ends = np.zeros((4, 3)), np.zeros((4, 3))
    for i, limb in enumerate(LIMBS):
        u, l, e = B[limb.upper], B[limb.lower], B[limb.end]
        d_up = pos[:, l] - pos[:, u]
        d_low = pos[:, e] - pos[:, l]
        n = _cross(_unit(d_up), _unit(d_low))
        weight = np.linalg.norm(n, axis=-1)
        local_n = rot.apply(rot.inverse(world[:, u]), _unit(n))
        if weight.sum() > 0.05 * len(weight):  # the limb was bent enough to show its hinge
            h = (local_n * weight[:, None]).sum(0)
            hinges[i] = h / max(np.linalg.norm(h), 1e-12)
        else:
            hinges[i] = _default_hinge(limb)
        ends[i] = _unit(rot.apply(rot.inverse(world[:, e]), _unit(d_low)).mean(0))
    return hinges, ends


def _pole_directions(world: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """Mean direction from the root-to-end line to the middle joint, in the frame of the
    bone the limb hangs from (UpperChest for arms, Hips for legs)."""
    out = np.zeros((4, 3))
    for i, limb in enumerate(LIMBS):
        u, l, e = B[limb.upper], B[limb.lower], B[limb.end]
        frame = HUMANOID_PARENTS[B[limb.root]] if limb.root else 0
        axis = _unit(pos[:, e] - pos[:, u])
        v = pos[:, l] - pos[:, u]
        v = v - np.sum(v * axis, axis=-1, keepdims=True) * axis
        local = rot.apply(rot.inverse(world[:, frame]), v)
        m = local.mean(0)
        if np.linalg.norm(m) < 1e-3:  # straight limbs all along: anatomical default
            m = np.array([0.0, 0.0, -1.0]) if limb.root else np.array([0.0, 0.0, 1.0])
        out[i] = m / np.linalg.norm(m)
    return out


def _default_hinge(limb: _Limb) -> np.ndarray:
    """Anatomical hinge in a clean T-pose frame: elbows bend forwards, knees backwards."""
    if "Leg" in limb.upper:
        return np.array([1.0, 0.0, 0.0])
    return np.array([0.0, -1.0, 0.0]) if limb.upper.startswith("Left") else np.array([0.0, 1.0, 0.0])


def _rest_relative(world: np.ndarray, pos: np.ndarray, roles) -> np.ndarray:
    out = np.zeros((N_ROLES, 7))
    out[:, 6] = 1.0
    inv_h = rot.inverse(world[:, 0])
    for role in roles:
        b = B[role.bone]
        out[role, :3] = rot.apply(inv_h, pos[:, b] - pos[:, 0]).mean(0)
        out[role, 3:] = _qmean(rot.multiply(inv_h, world[:, b]))
    return out


def calibrate_tpose(frames, roles: tuple[TrackerRole, ...] = TEN_POINT, *,
                    skeleton: Skeleton | None = None) -> Calibration:
    """Calibrate from a second of the performer standing in a T-pose.

    The straps are assumed to sit as ``trackers.NOMINAL_MOUNTS`` says (position); their
    rotations are measured. Proportions are scaled per body part (spine, each arm, each
    leg) from ``skeleton`` (default: ``humanoid_skeleton_default``) so the T-pose reaches
    the trackers; the facing is taken from the hands (left minus right is the left axis).
    """
    ts, P, Q, V = _as_arrays(frames)
    roles = tuple(sorted(set(roles)))
    for need in (R.HMD, R.WAIST, R.LEFT_HAND, R.RIGHT_HAND, R.LEFT_FOOT, R.RIGHT_FOOT):
        if need not in roles:
            raise UserError(f"T-pose calibration needs the {need.name} tracker; use the 6- or 10-point set")
    for role in roles:
        if not V[:, role].any():
            raise UserError(f"T-pose calibration saw no valid pose from the {role.name} tracker; switch it on "
                            f"(or use the 6-point set without elbows and knees) and calibrate again")
    mean_p = np.stack([P[V[:, r], r].mean(0) if V[:, r].any() else np.zeros(3) for r in range(N_ROLES)])
    mean_q = np.stack([_qmean(Q[V[:, r], r]) if V[:, r].any() else rot.IDENTITY for r in range(N_ROLES)])
    left = mean_p[R.LEFT_HAND] - mean_p[R.RIGHT_HAND]
    yaw = np.arctan2(-left[2], left[0])  # rotation about +Y taking +X onto the left axis
    facing = Rotation.from_rotvec([0.0, yaw, 0.0]).as_quat()
    base = skeleton if skeleton is not None else humanoid_skeleton_default()
    offsets = np.array(base.offsets, float)
    groups = {
        "spine": [B[b] for b in ("Spine", "Chest", "UpperChest", "Neck", "Head")],
        "left_arm": [B[b] for b in ("LeftShoulder", "LeftUpperArm", "LeftLowerArm", "LeftHand")],
        "right_arm": [B[b] for b in ("RightShoulder", "RightUpperArm", "RightLowerArm", "RightHand")],
        "left_leg": [B[b] for b in ("LeftUpperLeg", "LeftLowerLeg", "LeftFoot")],
        "right_leg": [B[b] for b in ("RightUpperLeg", "RightLowerLeg", "RightFoot")],
    }
    groups["left_leg"].append(B["LeftToes"])  # the foot tracker's place scales with the foot
    groups["right_leg"].append(B["RightToes"])
    names = list(groups)
    group_of = {j: g for g, n in enumerate(names) for j in groups[n]}
    # Unknowns: hips position (3) and one scale per group. Tracker k sits at
    # hips + R_f (sum over its chain of scale_g(j) * offset_j + frac_k * scale * offset_child
    # + perp_k): linear in the unknowns.
    rows, ys = [], []
    for role in roles:
        if not V[:, role].any():
            continue
        frac, perp, _ = NOMINAL_MOUNTS[role]
        a = np.zeros((3, 3 + len(names)))
        a[:, :3] = np.eye(3)
        parts = [(j, 1.0) for j in _chain(B[role.bone])]
        child = MOUNT_CHILD.get(role.bone)
        if child is not None and frac:
            parts.append((B[child], frac))
        for j, f in parts:
            if j in group_of:
                a[:, 3 + group_of[j]] += f * rot.apply(facing, offsets[j])
        rows.append(a)
        ys.append(mean_p[role] - rot.apply(facing, np.asarray(perp, float)))
    a, y = np.concatenate(rows), np.concatenate(ys)
    reg = np.diag([0.0, 0.0, 0.0] + [1e-2] * len(names))
    x = np.linalg.solve(a.T @ a + reg, a.T @ y + reg @ np.r_[np.zeros(3), np.ones(len(names))])
    hips = x[:3]
    scale = np.clip(x[3:], 0.5, 2.0)
    for g, n in enumerate(names):
        offsets[groups[n]] *= scale[g]
    skel = Skeleton(HUMANOID_BONES, HUMANOID_PARENTS, offsets)
    world = np.tile(facing, (1, len(HUMANOID_BONES), 1))
    pos = _fk_positions(world, hips[None], offsets)
    mount_p = np.zeros((N_ROLES, 3))
    mount_q = np.tile(rot.IDENTITY, (N_ROLES, 1))
    for role in roles:
        mount_p[role] = nominal_mount(role, skel)[0]
        mount_q[role] = rot.multiply(rot.inverse(facing), mean_q[role])
    neutral = np.tile(rot.IDENTITY, (len(HUMANOID_BONES), 1))
    neutral[0] = facing
    hinges, ends = _limb_geometry(world, pos)
    rest_rel = _rest_relative(world, pos, roles)
    poles = _pole_directions(world, pos)
    return Calibration(skel, roles, mount_p, mount_q, neutral, hinges, ends, rest_rel, poles, "t-pose")


# ------------------------------------------------------------------ hold and blend


def _relative(hp, hq, p, q):
    inv = rot.inverse(hq)
    return rot.apply(inv, p - hp), rot.multiply(inv, q)


def _compose(hp, hq, rp, rq):
    return hp + rot.apply(hq, rp), rot.multiply(hq, rq)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of every run of True in a 1-D boolean array."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


class _HoldBlend:
    """Hold of lost trackers and blend back on return (see the module doc), on bone poses
    (position, rotation) per role:

    * a lost limb / head bone keeps its last output pose relative to the hips, so it is
      carried along by the body;
    * a lost waist sits between the hip joints the two thigh trackers imply (10 points),
      turned from its last rotation to match them; without them it keeps its last
      rotation and follows the headset's translation; without that it stays put;
    * a returning tracker blends from that estimate to its live pose over ``blend_time``
      seconds (smoothstep: no step in position and none in velocity at either end).

    ``run`` takes any number of consecutive frames and carries its state over to the next
    call: the live path feeds one frame at a time, ``solve_batch`` a whole recording, and
    both get the same output. Work is vectorised over each stretch of a lost or returning
    tracker; frames where every tracker is live cost nothing.
    """

    def __init__(self, cal: Calibration, blend_time: float):
        self.cal = cal
        self.roles = tuple(cal.roles)
        self.limb_roles = tuple(r for r in self.roles if r != R.WAIST)
        self.blend_time = max(float(blend_time), 1e-6)
        off = cal.skeleton.offsets
        self._hip_axis = off[B["LeftUpperLeg"]] - off[B["RightUpperLeg"]]  # in the hips frame
        self._hip_mid = 0.5 * (off[B["LeftUpperLeg"]] + off[B["RightUpperLeg"]])
        self._has_knees = R.LEFT_KNEE in self.roles and R.RIGHT_KNEE in self.roles
        self.reset()

    def reset(self) -> None:
        self.prev_p = None  # last output (N_ROLES, 3), None before the first frame
        self.prev_q = None
        self.prev_head = None  # the live headset pose of the last frame, if it was valid
        self.lost = np.zeros(N_ROLES, bool)
        self.returned_at = np.full(N_ROLES, -np.inf)
        self.held_p = np.zeros((N_ROLES, 3))  # relative to the hips
        self.held_q = np.tile(rot.IDENTITY, (N_ROLES, 1))
        self.waist_mode = ""  # "knees", "head" or "still" while the waist is estimated
        self.waist_anchor: tuple = ()
        self.last_local = None  # the solver's last output rotations (sign continuity)

    def run(self, ts: np.ndarray, live_p: np.ndarray, live_q: np.ndarray, valid: np.ndarray):
        """Frames (T,), live bone poses (T, 10, 3/4), valid (T, 10) -> output poses and how
        live each role is (T, 10): 1 live, 0 held, in between while blending back."""
        T = len(ts)
        live = np.ones((T, N_ROLES))
        busy = self.lost.any() or (ts[0] - self.returned_at < self.blend_time).any()
        if not busy and valid[:, list(self.roles)].all():  # the common case: nothing to do
            self._remember(live_p[-1], live_q[-1], live_p[-1, R.HMD], live_q[-1, R.HMD], valid[-1])
            return live_p, live_q, live
        out_p, out_q = live_p.copy(), live_q.copy()
        if R.WAIST in self.roles:
            self._waist(ts, live_p, live_q, valid, out_p, out_q, live)
        for role in self.limb_roles:
            self._limb(role, ts, live_p, live_q, valid, out_p, out_q, live)
        self._remember(out_p[-1], out_q[-1], live_p[-1, R.HMD], live_q[-1, R.HMD], valid[-1])
        return out_p, out_q, live

    def _remember(self, p, q, head_p, head_q, valid) -> None:
        self.prev_p, self.prev_q = p.copy(), q.copy()
        self.prev_head = (head_p.copy(), head_q.copy()) if R.HMD in self.roles and valid[R.HMD] else None

    def _returns(self, role, ts, v):
        """Per frame: the time the role last came back (ffill), updating the state."""
        back = v & ~np.r_[~self.lost[role], v[:-1]]  # valid now, lost the frame before
        ret = np.where(back, ts, -np.inf)
        ret[0] = max(ret[0], self.returned_at[role])
        ret = np.maximum.accumulate(ret)
        self.returned_at[role] = ret[-1]
        self.lost[role] = not v[-1]
        return ret

    def _before(self, t, out_p, out_q):
        """The output pose of every role at the frame before chunk index t (None: none yet)."""
        if t > 0:
            return out_p[t - 1], out_q[t - 1]
        return (self.prev_p, self.prev_q) if self.prev_p is not None else (None, None)

    def _limb(self, role, ts, live_p, live_q, valid, out_p, out_q, live) -> None:
        v = valid[:, role]
        continuing = self.lost[role]  # a gap that began in an earlier chunk
        ret = self._returns(role, ts, v)
        blending = v & (ts - ret < self.blend_time)
        if v.all() and not blending.any():
            return
        W = R.WAIST
        events = [(g0, g1) for g0, g1 in _runs(~v)]
        if blending[0] and not (events and events[0][0] == 0):
            events.insert(0, (0, 0))  # a blend carried over from the previous chunk
        for k, (g0, g1) in enumerate(events):
            if g1 > g0:  # the gap: hold relative to the hips
                if not (g0 == 0 and continuing):
                    pp, pq = self._before(g0, out_p, out_q)
                    if pp is None:  # lost from the very start: the calibrated relation
                        rest = self.cal.rest_relative[role]
                        self.held_p[role], self.held_q[role] = rest[:3], rest[3:]
                    else:
                        self.held_p[role], self.held_q[role] = _relative(pp[W], pq[W], pp[role], pq[role])
                out_p[g0:g1, role], out_q[g0:g1, role] = _compose(out_p[g0:g1, W], out_q[g0:g1, W],
                                                                  self.held_p[role], self.held_q[role])
                live[g0:g1, role] = 0.0
            nxt = events[k + 1][0] if k + 1 < len(events) else len(ts)
            w = np.arange(g1, nxt)
            w = w[blending[w]]
            if len(w):  # coming back: from the held pose to the live one, relative to the hips
                a = _smoothstep((ts[w] - ret[w]) / self.blend_time)
                lp, lq = _relative(out_p[w, W], out_q[w, W], live_p[w, role], live_q[w, role])
                rp = self.held_p[role] + a[:, None] * (lp - self.held_p[role])
                rq = rot.slerp(np.broadcast_to(self.held_q[role], lq.shape), lq, a)
                out_p[w, role], out_q[w, role] = _compose(out_p[w, W], out_q[w, W], rp, rq)
                live[w, role] = a

    def _waist(self, ts, live_p, live_q, valid, out_p, out_q, live) -> None:
        W, H = R.WAIST, R.HMD
        v = valid[:, W]
        ret = self._returns(W, ts, v)
        estimate = ~v | (ts - ret < self.blend_time)
        if not estimate.any():
            self.waist_mode = ""
            return
        head_ok = valid[:, H] if H in self.roles else np.zeros(len(ts), bool)
        knees_ok = (valid[:, R.LEFT_KNEE] & valid[:, R.RIGHT_KNEE]) if self._has_knees else np.zeros(len(ts), bool)
        mode = np.where(knees_ok, 1, np.where(head_ok, 2, 3)) * estimate
        names = {1: "knees", 2: "head", 3: "still"}
        start = np.flatnonzero(np.diff(np.r_[0, mode]) != 0)
        stops = np.r_[start[1:], len(ts)]
        for t0, t1 in zip(start, stops):
            m = names.get(int(mode[t0]))
            if m is None:
                continue
            if not (t0 == 0 and self.waist_mode == m):
                self._anchor(m, t0, live_p, live_q, valid, out_p, out_q)
            self.waist_mode = m
            sl = slice(t0, t1)
            ep, eq = self._estimate(m, sl, live_p, live_q)
            a = np.where(v[sl], _smoothstep((ts[sl] - ret[sl]) / self.blend_time), 0.0)
            out_p[sl, W] = ep + a[:, None] * (live_p[sl, W] - ep)
            out_q[sl, W] = rot.slerp(eq, live_q[sl, W], a)
            live[sl, W] = a
        if not estimate[-1]:
            self.waist_mode = ""

    def _anchor(self, mode, t0, live_p, live_q, valid, out_p, out_q) -> None:
        """What the estimate keeps from the output just before it starts."""
        W, H = R.WAIST, R.HMD
        pp, pq = self._before(t0, out_p, out_q)
        if pp is not None:
            hp, hq = pp[W], pq[W]
        else:  # nothing seen yet: from the headset and the calibrated head-to-hips relation
            rest = self.cal.rest_relative[H]
            if H in self.roles and valid[t0, H]:
                hq = rot.multiply(live_q[t0, H], rot.inverse(rest[3:]))
                hp = live_p[t0, H] - rot.apply(hq, rest[:3])
            else:
                hp, hq = np.zeros(3), rot.IDENTITY.copy()
        if mode == "head":
            if t0 > 0 and valid[t0 - 1, H]:
                head = live_p[t0 - 1, H]
            elif t0 == 0 and self.prev_head is not None:
                head = self.prev_head[0]
            else:
                head = live_p[t0, H]
            self.waist_anchor = (hp - head, hq)
        else:
            self.waist_anchor = (hp, hq)

    def _estimate(self, mode, sl, live_p, live_q):
        n = sl.stop - sl.start
        if mode == "knees":
            # Both thigh trackers give the hip joints: the hips sit between them, turned
            # from their anchored rotation so their left axis runs from right to left hip.
            q0 = np.broadcast_to(self.waist_anchor[1], (n, 4))
            left = live_p[sl, R.LEFT_KNEE] - live_p[sl, R.RIGHT_KNEE]
            hq = rot.multiply(_swing(rot.apply(q0, self._hip_axis), left), q0)
            mid = 0.5 * (live_p[sl, R.LEFT_KNEE] + live_p[sl, R.RIGHT_KNEE])
            return mid - rot.apply(hq, self._hip_mid), hq
        if mode == "head":
            # The hips keep their rotation and follow the headset's translation (people
            # turn and nod their heads without their hips).
            offset, hq = self.waist_anchor
            return live_p[sl, R.HMD] + offset, np.broadcast_to(hq, (n, 4)).copy()
        hp, hq = self.waist_anchor
        return np.broadcast_to(hp, (n, 3)).copy(), np.broadcast_to(hq, (n, 4)).copy()


# ------------------------------------------------------------------ the solver


class TrackerSolver:
    """Solves tracker frames into humanoid pose frames for one performer.

    ``solve(poses)`` is the live path (stateful: hold/blend across calls);
    ``solve_batch(...)`` solves a whole recording at once with the same results.
    """

    def __init__(self, calibration: Calibration, performer: str = "", blend_time: float = DEFAULT_BLEND_TIME):
        self.cal = calibration
        self.performer = performer
        self.blend_time = float(blend_time)
        self._hold = _HoldBlend(calibration, self.blend_time)
        self._offsets = np.array(calibration.skeleton.offsets, float)
        self._lengths = np.linalg.norm(self._offsets, axis=1)
        self._k = _index_tables(calibration)

    @property
    def skeleton(self) -> Skeleton:
        return self.cal.skeleton

    def reset(self) -> None:
        self._hold.reset()

    # -- trackers -> bone poses
    def _bone_poses(self, P: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tracker poses (..., 10, 3/4) -> the bones' joint positions and world rotations."""
        bq = rot.multiply(Q, rot.inverse(self.cal.mount_rotations))
        bp = P - rot.apply(bq, self.cal.mount_positions)
        return bp, bq

    def solve(self, poses: TrackerPoses) -> PoseFrame:
        """One live frame (stateful: a lost tracker is held across calls)."""
        return self.solve_live([poses])[0]

    def solve_live(self, frames: list[TrackerPoses]) -> list[PoseFrame]:
        """Consecutive live frames at once (what one poll of a source delivered): the same
        result as ``solve`` on each in turn, at a fraction of the per-call overhead."""
        if not frames:
            return []
        ts, P, Q, V = _as_arrays(frames)
        root, local = self._solve(self._hold, ts, P, Q, V)
        return [PoseFrame(self.performer, float(t), root[i], local[i]) for i, t in enumerate(ts)]

    def solve_batch(self, timestamps, positions, orientations, valid=None) -> tuple[np.ndarray, np.ndarray]:
        """(T,) s, (T, 10, 3) cm, (T, 10, 4), (T, 10) bool -> root (T, 3), local rotations
        (T, 22, 4). Starts from a clean state and leaves the live state untouched."""
        ts = np.asarray(timestamps, float)
        V = np.ones((len(ts), N_ROLES), bool) if valid is None else np.asarray(valid, bool)
        return self._solve(_HoldBlend(self.cal, self.blend_time), ts, np.asarray(positions, float),
                           np.asarray(orientations, float), V)

    def _solve(self, hold: "_HoldBlend", ts, P, Q, V):
        bp, bq = self._bone_poses(P, Q)
        bp, bq, live = hold.run(ts, bp, bq, V)
        root, local = self._solve_core(bp, bq, live)
        # q and -q are one rotation: keep each bone's sign continuous in time (from the
        # previous call on), as interpolation and finite differences downstream need.
        if hold.last_local is not None:
            local = rot.canonical_hemisphere(np.concatenate([hold.last_local[None], local]), axis=0)[1:]
        else:
            local = rot.canonical_hemisphere(local, axis=0)
        hold.last_local = local[-1].copy()
        return root, local

    def solve_frames(self, frames: list[TrackerPoses]) -> Clip:
        """A recording of tracker frames -> a humanoid Clip (frame rate from the timestamps)."""
        ts, P, Q, V = _as_arrays(frames)
        root, local = self.solve_batch(ts, P, Q, V)
        fps = (len(ts) - 1) / (ts[-1] - ts[0]) if len(ts) > 1 and ts[-1] > ts[0] else 60.0
        return Clip(self.skeleton, local, root, fps)

    # -- the IK
    def _solve_core(self, bp: np.ndarray, bq: np.ndarray, live: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bone poses per role (T, 10, 3/4) and how live each is (T, 10) -> hips positions
        (T, 3), local rotations (T, 22, 4).
        Every step is vectorised over frames and, where bones do the same thing, over bones
        (the two clavicles, the four limbs), so one frame costs few numpy calls."""
        cal, off, lengths, k = self.cal, self._offsets, self._lengths, self._k
        T = bp.shape[0]
        world = np.empty((T, len(HUMANOID_BONES), 4))
        pos = np.empty((T, len(HUMANOID_BONES), 3))
        world[:, 0], pos[:, 0] = bq[:, R.WAIST], bp[:, R.WAIST]
        self._solve_spine(world, pos, bp[:, R.HMD], bq[:, R.HMD])
        # Clavicles: neutral, or aimed at the socket the elbow tracker implies.
        sh, chest = k["shoulders"], k["chest"]
        pos[:, sh] = pos[:, chest, None] + rot.apply(world[:, chest, None], off[sh])
        q = rot.multiply(world[:, chest, None], cal.neutral[sh])
        if k["aimed_shoulders"]:
            a_idx, roles = k["aimed_shoulders"], k["aimed_socket_roles"]
            qa = q[:, a_idx]
            sock = bp[:, roles] - pos[:, sh][:, a_idx]
            q[:, a_idx] = rot.multiply(_swing(rot.apply(qa, off[k["upper"][a_idx]]), sock), qa)
        world[:, sh] = q
        # The four limbs at once: two-bone IK from socket / hip to wrist / ankle.
        up, lo, end, par = k["upper"], k["lower"], k["end"], k["upper_parent"]
        pos[:, up] = pos[:, par] + rot.apply(world[:, par], off[up])
        target = bp[:, k["end_roles"]]
        pole = np.empty((T, 4, 3))
        wp, np_ = k["with_pole"], k["without_pole"]
        if wp:  # the elbow / knee the tracker implies
            pr = k["pole_roles"][wp]
            pole[:, wp] = bp[:, pr] + rot.apply(bq[:, pr], off[lo[wp]])
        for i in np_:
            if LIMBS[i].tip:  # knees: the direction they pointed at calibration, in the hips frame
                ahead = rot.apply(world[:, 0], cal.pole_directions[i])
                pole[:, i] = 0.5 * (pos[:, up[i]] + target[:, i]) + 100.0 * ahead
            else:  # elbows: back along the forearm from the wrist (the hand tracker's rotation)
                pole[:, i] = target[:, i] - lengths[end[i]] * rot.apply(bq[:, LIMBS[i].end_role], cal.end_directions[i])
        # A hint towards where elbows / knees usually point keeps the bend plane defined
        # when the pole lies on the reach line (a straight limb). It grows while the hand /
        # foot is held: a live pole against a held end would swing the plane about.
        weight = POLE_HINT_CM + HELD_POLE_HINT_CM * (1.0 - live[:, k["end_roles"]])
        hint = weight[..., None] * rot.apply(world[:, k["pole_frames"]], cal.pole_directions)
        knee, hinge = _two_bone(pos[:, up], target, lengths[lo][:, None], lengths[end][:, None], pole, hint)
        if wp:  # keep the tracker's twist, turn the bone onto the solved elbow / knee
            q0 = bq[:, k["pole_roles"][wp]]
            world[:, up[wp]] = rot.multiply(_swing(rot.apply(q0, off[lo[wp]]), knee[:, wp] - pos[:, up[wp]]), q0)
        if np_:  # twist from the learned hinge axis
            world[:, up[np_]] = _align(off[lo[np_]], cal.hinges[np_], knee[:, np_] - pos[:, up[np_]], hinge[:, np_])
        pos[:, lo] = pos[:, up] + rot.apply(world[:, up], off[lo])
        q = rot.multiply(world[:, up], cal.neutral[lo])
        world[:, lo] = rot.multiply(_swing(rot.apply(q, off[end]), target - pos[:, lo]), q)
        world[:, end] = bq[:, k["end_roles"]]
        world[:, k["toes"]] = rot.multiply(world[:, k["feet"]], cal.neutral[k["toes"]])
        local = world.copy()
        local[:, 1:] = rot.multiply(rot.inverse(world[:, k["parents"]]), world[:, 1:])
        return bp[:, R.WAIST].copy(), local

    def _solve_spine(self, world, pos, head_p, head_q) -> None:
        off, k = self._offsets, self._k
        ids, nxt = k["spine"], k["spine_next"]
        hips_q = world[:, 0]
        dev = rot.multiply(rot.multiply(rot.inverse(hips_q), head_q), k["inv_neutral_head"])
        v = Rotation.from_quat(dev).as_rotvec()
        base = pos[:, 0] + rot.apply(hips_q, off[ids[0]])
        goal = head_p - base
        T = len(v)
        # Share the deviation out along the chain, on top of each bone's neutral rotation.
        g = Rotation.from_rotvec((v[:, None, :] * np.asarray(SPINE_WEIGHTS)[None, :, None]).reshape(-1, 3))
        qs = rot.multiply(hips_q[:, None], rot.multiply(g.as_quat().reshape(T, len(ids), 4), k["neutral_spine"]))
        # ps[:, i]: the joint after spine bone i; ps[:, -1] is where the chain puts the head.
        ps = base[:, None] + np.cumsum(rot.apply(qs, off[nxt]), axis=1)
        # Turn the whole chain about its base so it points at the head joint.
        turn = _swing(ps[:, -1] - base, goal)[:, None]
        world[:, ids] = rot.multiply(turn, qs)
        pos[:, ids[0]] = base
        pos[:, ids[1:]] = base[:, None] + rot.apply(turn, ps[:, :-1] - base[:, None])
        # The neck finally aims at the head joint (what is left of the length error stays).
        n, h = ids[-1], B["Head"]
        world[:, n] = rot.multiply(_swing(rot.apply(world[:, n], off[h]), head_p - pos[:, n]), world[:, n])
        world[:, h] = head_q
        pos[:, h] = pos[:, n] + rot.apply(world[:, n], off[h])


def _index_tables(cal: Calibration) -> dict:
    """Index arrays the vectorised IK gathers with (fixed per calibration)."""
    idx = lambda names: np.array([B[n] for n in names], dtype=np.intp)
    k = {
        "spine": idx(SPINE), "spine_next": idx(SPINE[1:] + ("Head",)),
        "chest": B["UpperChest"], "shoulders": idx([l.root for l in LIMBS[:2]]),
        "upper": idx([l.upper for l in LIMBS]), "lower": idx([l.lower for l in LIMBS]),
        "end": idx([l.end for l in LIMBS]), "feet": idx([l.end for l in LIMBS[2:]]),
        "toes": idx([l.tip for l in LIMBS[2:]]),
        "upper_parent": idx([l.root or "Hips" for l in LIMBS]),
        "pole_frames": idx(["UpperChest" if l.root else "Hips" for l in LIMBS]),
        "end_roles": np.array([int(l.end_role) for l in LIMBS], dtype=np.intp),
        "pole_roles": np.array([int(l.pole_role) for l in LIMBS], dtype=np.intp),
        "parents": np.array(HUMANOID_PARENTS[1:], dtype=np.intp),
    }
    has_pole = [cal.has(l.pole_role) for l in LIMBS]
    k["with_pole"] = [i for i in range(4) if has_pole[i]]
    k["without_pole"] = [i for i in range(4) if not has_pole[i]]
    k["aimed_shoulders"] = [i for i in range(2) if has_pole[i]]
    k["aimed_socket_roles"] = np.array([int(LIMBS[i].pole_role) for i in k["aimed_shoulders"]], dtype=np.intp)
    # Neutral world rotations of the spine chain and the head, relative to the hips.
    acc, chain = rot.IDENTITY, []
    for j in list(k["spine"]) + [B["Head"]]:
        acc = rot.multiply(acc, cal.neutral[j])
        chain.append(acc)
    k["neutral_spine"] = np.stack(chain[:-1])
    k["inv_neutral_head"] = rot.inverse(chain[-1])
    return k


def _two_bone(root: np.ndarray, target: np.ndarray, a, b, pole: np.ndarray, hint: np.ndarray | None = None):
    """Middle joint of two-bone chains of lengths a, b from ``root`` reaching towards
    ``target`` and bending towards ``pole`` (plus the vector ``hint``, which decides only
    when the pole is close to the reach line). Returns (joint, hinge axis)."""
    d = target - root
    dist = np.linalg.norm(d, axis=-1, keepdims=True)
    u = _unit(d, np.array([0.0, -1.0, 0.0]))
    a, b = np.asarray(a, float), np.asarray(b, float)
    lo, hi = np.abs(a - b) + 1e-4, np.maximum(a + b - 1e-4, np.abs(a - b) + 1e-4)
    dist = np.clip(dist, lo, hi)
    cos_a = np.clip((a * a + dist * dist - b * b) / np.maximum(2 * a * dist, 1e-12), -1.0, 1.0)
    sin_a = np.sqrt(1.0 - cos_a * cos_a)
    v = pole - root if hint is None else pole - root + hint
    v = v - np.sum(v * u, axis=-1, keepdims=True) * u
    n = _norm(v)
    if np.any(n <= 1e-9):  # pole on the reach line: bend towards any perpendicular
        fallback = _unit(_cross(u, np.broadcast_to([1.0, 0.0, 0.0], u.shape)), np.array([0.0, 0.0, 1.0]))
        v = np.where(n > 1e-9, v, fallback)
    v = _unit(v)
    joint = root + a * (cos_a * u + sin_a * v)
    return joint, -_cross(u, v)


# ------------------------------------------------------------------ the daemon's source


class SolvedTrackerSource(Source):
    """A daemon source (``drivers.sources.Source``) that solves tracker samples
    into humanoid pose frames: ``serial:///dev/ttyUSB0?baud=921600&points=10&calibrate=1``.

    The first ``calibrate`` seconds of tracker frames are the T-pose calibration (the
    performer stands in a T-pose when the source starts); frames are solved from then on.
    Tracker frames are grouped by device timestamp (``FrameAssembler``); a frame is
    complete when the next one starts or when no sample has come for ``flush_after``
    seconds. Device time is mapped onto the daemon's clock with a fixed offset taken at
    the first frame, and the solved poses are resampled onto a 60 Hz grid (the daemon's
    rate, whatever the trackers' rate): each grid time between two solved frames gets
    their interpolation (slerp), which costs at most one tracker frame of latency; across
    a gap longer than ``max_gap`` the pose is not interpolated. Never raises from ``poll``.
    """

    fps = 60.0
    max_gap = 0.25

    def __init__(self, trackers, performer: str, points: int = 10, calibrate_seconds: float = 1.0,
                 blend_time: float = DEFAULT_BLEND_TIME, calibration: Calibration | None = None,
                 flush_after: float = 0.02):
        from .trackers import FrameAssembler, roles_for_points

        self.trackers = trackers
        self.performer = performer
        self.roles = roles_for_points(points)
        self.calibrate_seconds = float(calibrate_seconds)
        self.blend_time = blend_time
        self.flush_after = flush_after
        self.assembler = FrameAssembler()
        self.solver = None if calibration is None else TrackerSolver(calibration, performer, blend_time)
        self.skeleton = None if calibration is None else calibration.skeleton
        self._calibration_frames: list[TrackerPoses] = []
        self._offset: float | None = None
        self._last_arrival = -np.inf
        self._prev: PoseFrame | None = None  # the last solved frame (daemon time)
        self._next_tick: float | None = None  # the next 60 Hz grid time to emit
        self.frames_solved = 0
        self.solve_errors = 0
        self.calibration_failures = 0
        self.last_problem = ""

    def start(self, now: float) -> None:
        self._last_arrival = now

    def poll(self, now: float) -> list[PoseFrame]:
        try:
            samples = self.trackers.poll()
        except Exception as exc:  # a tracker source must not take the daemon down
            self.last_problem = str(exc)
            samples = []
        frames = self.assembler.feed(samples)
        if samples:
            self._last_arrival = now
        elif now - self._last_arrival > self.flush_after:
            last = self.assembler.flush()
            if last is not None:
                frames.append(last)
        out, live = [], []
        for f in frames:
            if self._offset is None:
                self._offset = now - f.timestamp
            if self.solver is None:
                self._calibrate(f)
                continue
            live.append(f)
        try:
            solved = self.solver.solve_live(live) if live else []
        except Exception as exc:  # a bug must not take the daemon down: count it, say it once
            self.solve_errors += 1
            if self.solve_errors == 1:
                import logging

                logging.getLogger("stylecast.drivers.solver").exception("%s: solver failed", self.performer)
            self.last_problem = f"solver failed: {exc}"
            solved = []
        for pf in solved:
            self.frames_solved += 1
            out += self._resample(PoseFrame(self.performer, pf.timestamp + self._offset, pf.root_position,
                                            pf.rotations))
        return out

    def _resample(self, cur: PoseFrame) -> list[PoseFrame]:
        """60 Hz grid frames up to ``cur``'s time, interpolated from the previous solve."""
        prev, self._prev = self._prev, cur
        step = 1.0 / self.fps
        if prev is None or self._next_tick is None or cur.timestamp - prev.timestamp > self.max_gap:
            self._next_tick = cur.timestamp + step
            return [cur]
        out = []
        span = cur.timestamp - prev.timestamp
        while self._next_tick <= cur.timestamp + 1e-4:  # (device clocks tick in µs)
            a = 1.0 if span <= 0 else (self._next_tick - prev.timestamp) / span
            out.append(PoseFrame(self.performer, self._next_tick,
                                 prev.root_position + a * (cur.root_position - prev.root_position),
                                 rot.slerp(prev.rotations, cur.rotations, a)))
            self._next_tick += step
        return out

    def _calibrate(self, frame: TrackerPoses) -> None:
        import logging

        self._calibration_frames.append(frame)
        first = self._calibration_frames[0].timestamp
        if frame.timestamp - first < self.calibrate_seconds:
            return
        try:
            cal = calibrate_tpose(self._calibration_frames, self.roles)
        except UserError as exc:
            self.calibration_failures += 1
            self.last_problem = str(exc)
            logging.getLogger("stylecast.drivers.solver").warning("%s: calibration failed (%s); trying again",
                                                                 self.performer, exc)
            self._calibration_frames = []
            return
        self.solver = TrackerSolver(cal, self.performer, self.blend_time)
        self.skeleton = cal.skeleton
        self._calibration_frames = []

    @property
    def finished(self) -> bool:
        return False

    @property
    def calibrated(self) -> bool:
        return self.solver is not None

    def counters(self) -> dict:
        out = {"frames_solved": self.frames_solved, "solve_errors": self.solve_errors, "calibrated": self.calibrated,
               "calibration_failures": self.calibration_failures, "late_samples": self.assembler.late_samples}
        decoder = getattr(self.trackers, "decoder", None)
        if decoder is not None:
            out.update(packets=decoder.frames, bad_frames=dict(decoder.bad_frames),
                       garbage_bytes=decoder.garbage_bytes)
        stats = getattr(self.trackers, "stats", None)
        if stats is not None and hasattr(stats, "disconnects"):
            out.update(disconnects=stats.disconnects, reconnects=stats.reconnects,
                       open_failures=stats.open_failures)
        return out

    def close(self) -> None:
        close = getattr(self.trackers, "close", None)
        if close is not None:
            close()


def open_source(url, performer: str) -> SolvedTrackerSource:
    """The daemon's ``serial://`` factory (``drivers.sources``):
    ``serial:///dev/ttyUSB0?baud=921600&points=10&calibrate=1&blend=0.3``."""
    from .serial_trackers import DEFAULT_BAUD, SerialTrackerSource

    opts = url.take({"baud": (int, DEFAULT_BAUD), "points": (int, 10), "calibrate": (float, 1.0),
                     "blend": (float, DEFAULT_BLEND_TIME)})
    device = (url.host + url.path) if url.host else url.path
    if not device:
        raise UserError(f"{url.text}: give a device, as in serial:///dev/ttyUSB0?baud=921600")
    if not 0.1 <= opts["calibrate"] <= 60:
        raise UserError(f"{url.text}: calibrate={opts['calibrate']} must be between 0.1 and 60 seconds")
    if not 0.0 <= opts["blend"] <= 5:
        raise UserError(f"{url.text}: blend={opts['blend']} must be between 0 and 5 seconds")
    trackers = SerialTrackerSource(f"serial://{device}?baud={opts['baud']}")
    return SolvedTrackerSource(trackers, performer, opts["points"], opts["calibrate"], opts["blend"])
