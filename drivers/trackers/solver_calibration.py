"""Calibration: what the solver learns about one performer and their straps.

``calibrate_known_pose`` (frames during which the humanoid pose is known: tests, the
bench, a recorded calibration motion) and ``calibrate_tpose`` (a second of T-pose, what a
live source does) both return a ``Calibration``: the tracker straps, the performer's bone
lengths, their neutral posture (local rotations of untracked bones), the hinge axes and
the default poles. Runs once per performer, so it favours clarity over speed (scipy
Rotation is fine here; it is kept off the per-frame path).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from stylecast.motion import rotations as rot
from stylecast.motion.clip import Clip
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import HUMANOID_BONES, HUMANOID_PARENTS, humanoid_skeleton_default
from stylecast.motion.skeleton import Skeleton

from stylecast.drivers.trackers.solver_body import LIMBS, N_ROLES, B, R, _as_arrays, _chain, _fk_positions, _Limb, _local_to_world
from stylecast.drivers.trackers.solver_math import _cross, _qmean, _unit
from stylecast.drivers.trackers.trackers import MOUNT_CHILD, NOMINAL_MOUNTS, TEN_POINT, TrackerRole, nominal_mount


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
