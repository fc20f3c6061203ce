"""The analytic IK: bone poses of the tracked roles -> world and local rotations of the
whole humanoid. Pure arithmetic, no state.

* Hips: the waist tracker. Head: the headset.
* Spine (Spine, Chest, UpperChest, Neck): the rotation from the hips to the head, beyond
  the performer's neutral posture, is shared out along the chain (``SPINE_WEIGHTS``), the
  chain is turned about its base to point at the head joint, and the neck finally aims at
  it.
* Arms and legs: two-bone IK from the shoulder socket / hip joint to the wrist / ankle
  (from the hand / foot tracker). With 10 points the elbow / knee tracker is the pole
  target and gives the upper bone's twist, and its socket estimate aims the clavicle.
  With 6 points an elbow is sought back along the forearm from the wrist (the forearm's
  direction in the hand frame is learned at calibration), a knee where it pointed at
  calibration in the hips frame; the twist comes from the learned hinge axis. A weak hint
  towards the usual bend direction keeps the bend plane defined for straight limbs and
  strong while the hand / foot is held.
* Hands and feet take their trackers' rotations; toes keep their neutral rotation.

``pose`` is written once on components (``solver_math``): ``solve_ik`` runs it on Python
floats frame by frame for a few frames (the live path; measured 20x cheaper than the same
code on one-frame numpy arrays, where each of its ~4,000 numpy calls costs about a
microsecond whatever the size) and on numpy columns for many (recordings), in blocks so
the temporaries stay bounded.
"""

from __future__ import annotations

from itertools import chain
from typing import NamedTuple

import numpy as np

from stylecast.motion import rotations as rot
from stylecast.motion.humanoid import HUMANOID_PARENTS

from stylecast.drivers.trackers.solver_body import HELD_POLE_HINT_CM, LIMBS, N_BONES, POLE_HINT_CM, SPINE, SPINE_WEIGHTS, B, R
from stylecast.drivers.trackers.solver_calibration import Calibration
from stylecast.drivers.trackers.solver_math import (ARRAY, SCALAR, add, aim, align, frame, local_rotations, place, qmul, qmul_conj, rotate,
                          scale, sub, swing, two_bone)

WAIST, HMD = int(R.WAIST), int(R.HMD)
SCALAR_FRAMES = 32  # up to this many frames, frame by frame on floats beats numpy columns (measured)
BLOCK = 8192  # frames per block of numpy columns: 64 kB temporaries (smaller blocks, more calls: slower, measured)


def _t(a) -> tuple:
    return tuple(float(x) for x in a)


class _LimbTable(NamedTuple):
    """One limb's bones and calibrated constants, as Python floats (they combine with
    both floats and arrays). A tuple so that ``pose`` unpacks it in one step."""

    root: int  # clavicle bone, -1 for legs
    upper: int
    lower: int
    end: int
    tip: int  # toes, -1 for arms
    end_role: int
    pole_role: int
    with_pole: bool  # its elbow / knee tracker is in the set
    off_root: tuple
    neutral_root: tuple
    off_upper: tuple
    off_lower: tuple
    off_end: tuple
    neutral_lower: tuple
    neutral_tip: tuple
    len_lower: float
    len_end: float
    pole_direction: tuple  # in the frame of pole_frame
    pole_frame: int  # UpperChest for arms, Hips for legs
    end_direction: tuple  # elbow -> wrist in the hand frame (6 points)
    hinge_frame: tuple  # frame(off_lower, hinge): what ``align`` turns (6 points)


class IKTables:
    """Everything ``pose`` needs from a calibration, computed once per performer."""

    def __init__(self, cal: Calibration):
        off = np.array(cal.skeleton.offsets, float)
        lengths = np.linalg.norm(off, axis=1)
        neutral = np.asarray(cal.neutral, float)
        self.spine = tuple(B[n] for n in SPINE)
        self.off_spine0 = _t(off[self.spine[0]])
        self.head = B["Head"]
        self.off_head = _t(off[self.head])
        # Neutral world rotations of the spine chain and the head, relative to the hips.
        acc, neutral_world = rot.IDENTITY, []
        for j in self.spine + (B["Head"],):
            acc = rot.multiply(acc, neutral[j])
            neutral_world.append(acc)
        self.inv_neutral_head = _t(rot.inverse(neutral_world[-1]))
        nxt = [B[n] for n in SPINE[1:] + ("Head",)]
        self.spine_links = tuple((w, _t(q), _t(off[j])) for w, q, j in zip(SPINE_WEIGHTS, neutral_world[:-1], nxt))
        self.limbs = []
        for i, limb in enumerate(LIMBS):
            root = B[limb.root] if limb.root else -1
            up, lo, end = B[limb.upper], B[limb.lower], B[limb.end]
            tip = B[limb.tip] if limb.tip else -1
            f0 = frame(_t(off[lo]), _t(cal.hinges[i]), SCALAR)
            self.limbs.append(_LimbTable(
                root, up, lo, end, tip, int(limb.end_role), int(limb.pole_role), cal.has(limb.pole_role),
                _t(off[root]) if root >= 0 else (), _t(neutral[root]) if root >= 0 else (),
                _t(off[up]), _t(off[lo]), _t(off[end]), _t(neutral[lo]), _t(neutral[tip]) if tip >= 0 else (),
                float(lengths[lo]), float(lengths[end]), _t(cal.pole_directions[i]),
                B["UpperChest"] if limb.root else 0, _t(cal.end_directions[i]), f0))
        self.parents = tuple(HUMANOID_PARENTS)


def pose(k: IKTables, bp, bq, live, xp, prev=None):
    """One IK solve. ``bp[role]`` (x, y, z), ``bq[role]`` (x, y, z, w): the bone pose each
    tracker gives (after hold and blend); ``live[role]``: how live it is (None: all live).
    Components are floats or arrays (``xp`` says which). Returns the local rotations of
    every bone (a list of quaternion tuples, HUMANOID_BONES order), with signs on the side
    of ``prev``'s (the previous frame's output, floats only) if given."""
    world = [None] * N_BONES
    hp, hq = bp[WAIST], bq[WAIST]
    world[0] = hq
    head_p, head_q = bp[HMD], bq[HMD]

    # Spine: share the hips->head deviation from neutral out along the chain, on top of
    # each bone's neutral rotation; ps[i] is the joint after spine bone i (ps[-1]: where
    # the chain puts the head), summed as np.cumsum did.
    v = xp.log_map(qmul(qmul_conj(hq, head_q), k.inv_neutral_head))
    base = place(hp, hq, k.off_spine0)
    qs, ps, cum = [], [], None
    for w, neutral, off_next in k.spine_links:
        q = qmul(hq, qmul(xp.exp_map(v, w), neutral))
        r = rotate(q, off_next)
        cum = r if cum is None else add(cum, r)
        qs.append(q)
        ps.append(add(base, cum))
    # Turn the whole chain about its base so it points at the head joint.
    turn = swing(sub(ps[-1], base), sub(head_p, base), xp)
    for j, q in zip(k.spine, qs):
        world[j] = qmul(turn, q)
    chest_p = add(base, rotate(turn, sub(ps[1], base)))  # the UpperChest joint
    neck_p = add(base, rotate(turn, sub(ps[2], base)))
    # The neck finally aims at the head joint (what is left of the length error stays).
    neck = k.spine[3]
    world[neck] = aim(world[neck], k.off_head, sub(head_p, neck_p), xp)
    world[k.head] = head_q
    chest_q = world[k.spine[2]]

    for (root, upper, lower, end, tip, end_role, pole_role, with_pole, off_root, neutral_root, off_upper, off_lower,
         off_end, neutral_lower, neutral_tip, len_lower, len_end, pole_direction, pole_frame, end_direction,
         hinge_frame) in k.limbs:
        if root >= 0:  # clavicle: neutral, or aimed at the socket the elbow tracker implies
            par_p = place(chest_p, chest_q, off_root)
            par_q = qmul(chest_q, neutral_root)
            if with_pole:
                par_q = aim(par_q, off_upper, sub(bp[pole_role], par_p), xp)
            world[root] = par_q
        else:
            par_p, par_q = hp, hq
        # Two-bone IK from socket / hip to wrist / ankle.
        pu = place(par_p, par_q, off_upper)
        target = bp[end_role]
        if with_pole:  # the elbow / knee the tracker implies
            pole = place(bp[pole_role], bq[pole_role], off_lower)
        elif tip >= 0:  # knees: the direction they pointed at calibration, in the hips frame
            pole = add(scale(add(pu, target), 0.5), scale(rotate(hq, pole_direction), 100.0))
        else:  # elbows: back along the forearm from the wrist (the hand tracker's rotation)
            pole = sub(target, scale(rotate(bq[end_role], end_direction), len_end))
        # A hint towards where elbows / knees usually point keeps the bend plane defined
        # when the pole lies on the reach line (a straight limb). It grows while the hand /
        # foot is held: a live pole against a held end would swing the plane about.
        weight = POLE_HINT_CM if live is None else POLE_HINT_CM + HELD_POLE_HINT_CM * (1.0 - live[end_role])
        hint = scale(rotate(world[pole_frame], pole_direction), weight)
        knee, hinge = two_bone(pu, target, len_lower, len_end, pole, hint, xp)
        if with_pole:  # keep the tracker's twist, turn the bone onto the solved elbow / knee
            wu = aim(bq[pole_role], off_lower, sub(knee, pu), xp)
        else:  # twist from the learned hinge axis
            wu = align(hinge_frame, sub(knee, pu), hinge, xp)
        world[upper] = wu
        pl = place(pu, wu, off_lower)
        world[lower] = aim(qmul(wu, neutral_lower), off_end, sub(target, pl), xp)
        world[end] = bq[end_role]
        if tip >= 0:
            world[tip] = qmul(world[end], neutral_tip)
    return local_rotations(world, k.parents, prev)


def solve_ik(k: IKTables, bp: np.ndarray, bq: np.ndarray, live: np.ndarray | None,
             last: np.ndarray | None) -> np.ndarray:
    """Bone poses per role (T, 10, 3/4) and how live each is ((T, 10) or None: all live)
    -> local rotations (T, 22, 4), each bone's sign continuous in time from ``last``
    (the previous output frame (22, 4), if any): q and -q are one rotation, and
    interpolation and finite differences downstream need the continuous one."""
    T = len(bp)
    if T <= SCALAR_FRAMES:
        P, Q = bp.tolist(), bq.tolist()
        L = [None] * T if live is None else live.tolist()
        prev = None if last is None else last.tolist()
        out = []
        for i in range(T):
            prev = pose(k, P[i], Q[i], L[i], SCALAR, prev)
            out.append(prev)
        # (np.array on the nested list takes twice as long: it discovers the shape)
        return np.fromiter(chain.from_iterable(chain.from_iterable(out)), np.float64, T * N_BONES * 4).reshape(
            T, N_BONES, 4)
    out = np.empty((T, N_BONES, 4))
    for s in range(0, T, BLOCK):
        e = min(T, s + BLOCK)
        # (roles, components, frames): each component a contiguous row
        P = np.ascontiguousarray(bp[s:e].transpose(1, 2, 0))
        Q = np.ascontiguousarray(bq[s:e].transpose(1, 2, 0))
        L = None if live is None else np.ascontiguousarray(live[s:e].T)
        local = pose(k, [tuple(p) for p in P], [tuple(q) for q in Q], L, ARRAY)
        out[s:e] = np.array(local).transpose(2, 0, 1)
    if last is not None:
        return rot.canonical_hemisphere(np.concatenate([last[None], out]), axis=0)[1:]
    return rot.canonical_hemisphere(out, axis=0)


class BonePoses:
    """Tracker poses -> the poses of the bones they are strapped to, over arrays.

    bone rotation = tracker rotation * strap^-1; joint = tracker position - bone rotation
    applied to the strap offset, which is the tracker rotation applied to the constant
    strap^-1 (offset). Both are linear in the tracker quaternion q (the first) or in its
    outer product q q^T (the second), so each is one matmul with a per-role table,
    whatever the number of frames: a dozen numpy calls for a live frame. The tracker
    quaternions are normalised on the way (scipy's apply, used before, did that too).
    """

    def __init__(self, cal: Calibration):
        inv = rot.inverse(np.asarray(cal.mount_rotations, float))  # (10, 4)
        # q * c = right @ q, right[i, a] the coefficient of q_a in (q * c)_i: (10, 4, 4)
        eye = np.eye(4)
        self._right = np.stack([rot.multiply(eye, c).T for c in inv])
        v = rot.apply(inv, np.asarray(cal.mount_positions, float))  # (10, 3)
        # apply(q, v)_o = sum_ij q_i q_j a[i, j, o] / |q|^2 (the rotation matrix of q, times
        # |q|^2, applied to v), and o = 3 gives |q|^2 itself.
        a = np.zeros((len(v), 4, 4, 4))
        X, Y, Z, W = 0, 1, 2, 3
        v0, v1, v2 = v[:, 0], v[:, 1], v[:, 2]
        for (i, j, o, c) in (
                (W, W, 0, v0), (X, X, 0, v0), (Y, Y, 0, -v0), (Z, Z, 0, -v0),
                (X, Y, 0, 2 * v1), (W, Z, 0, -2 * v1), (X, Z, 0, 2 * v2), (W, Y, 0, 2 * v2),
                (X, Y, 1, 2 * v0), (W, Z, 1, 2 * v0), (W, W, 1, v1), (X, X, 1, -v1), (Y, Y, 1, v1),
                (Z, Z, 1, -v1), (Y, Z, 1, 2 * v2), (W, X, 1, -2 * v2),
                (X, Z, 2, 2 * v0), (W, Y, 2, -2 * v0), (Y, Z, 2, 2 * v1), (W, X, 2, 2 * v1),
                (W, W, 2, v2), (X, X, 2, -v2), (Y, Y, 2, -v2), (Z, Z, 2, v2),
                (X, X, 3, 1.0), (Y, Y, 3, 1.0), (Z, Z, 3, 1.0), (W, W, 3, 1.0)):
            a[:, i, j, o] += c
        self._quadratic = np.ascontiguousarray(a.reshape(len(v), 16, 4).transpose(0, 2, 1))  # (10, 4, 16): [o, ij]

    def __call__(self, P: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(T, 10, 3), (T, 10, 4) -> bone joint positions (T, 10, 3), rotations (T, 10, 4)."""
        # Layout (role, component, frame): each role's products are then one matmul
        # (4 x 16) @ (16 x T) that BLAS runs at speed; the frame-major (T x 16) @ (16 x 4)
        # ran 4x slower, and one tiny product per frame far slower still (measured).
        n, T = Q.shape[1], Q.shape[0]
        q = np.ascontiguousarray(Q.transpose(1, 2, 0))  # (10, 4, T)
        m = np.matmul(self._quadratic, (q[:, :, None] * q[:, None]).reshape(n, 16, T))
        # m: (10, 4, T), the rotated offset * |q|^2, and |q|^2
        n2 = np.maximum(m[:, 3:], 1e-300)  # absent roles may hold zeros: no NaN from them
        bq = (np.matmul(self._right, q) / np.sqrt(n2)).transpose(2, 0, 1)
        bp = P - (m[:, :3] / n2).transpose(2, 0, 1)
        return bp, bq
