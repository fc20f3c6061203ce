"""Many performers at once (``FootLock.plan`` + ``solve_lock_jobs``): ``apply`` is a plan
(the lock's weights and floor for the frames) and a solve; the daemon plans each
performer's frame of a tick and solves them all in one vectorised pass, each frame with
its own performer's proportions (per-row bone offsets in ``leg_chain``/``solve_legs``),
each lock's pelvis and stance state advanced in order.

Floor (``_keep_above_floor``): a foot in the air whose ankle would go below its
standing height over the floor, or whose ball would go below the floor, is lifted onto it
by the same IK; near the floor, it keeps the input's own clearance too (a landing heel
is not set down early and dragged).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .. import rotations as rot
from .amplitude import amplitude_frames
from .legs import LEG_INDEX, leg_chain, solve_legs
from .stance import stance_targets

if TYPE_CHECKING:  # only for annotations: the lock imports this module
    from .lock import FootLock

FLOOR_MARGIN = 1.0  # cm above the floor from which a foot in the air is eased up (``_soft_floor``)
# cm of lift a foot needs before the floor step bends its leg fully (``_keep_above_floor``):
# a leg switched into the IK for a lift of a hundredth of a millimetre still moved its knee
# by the difference of the two solutions
FLOOR_LIFT_EASE = 0.5
# cm above its floor (the ankle: above its standing height) around which a foot in the air
# stops keeping the input's own clearance (``kept_clearance``, ``_keep_above_floor``). With
# the floor alone, the lowered pelvis set a landing heel on the floor up to 11 frames
# before the input's and dragged it there (a held-out walk made exhausted: the ankle at
# standing height moving 1.5-2 cm a frame where the input's was 1.3-2 cm up), and the
# output's skating read on its own contacts was 1.45x the input's in walks (real exhausted
# walks 0.95-1.03x the real normal ones'). Higher up the restyle lowers or lifts a swing freely.
CLEARANCE_BAND = 5.0
# cm a foot near the floor may go below the input's own (the soft edge's width is
# FLOOR_MARGIN: within half of it the clearance meets the input's with a smooth corner)
CLEARANCE_SLACK = 0.5
# cm a free foot's ``Pace`` carry (or its way to the input's path) must reach before its
# leg is fully moved by it (``_carry_free_feet``, ``_follow_input_path``), for
# FLOOR_LIFT_EASE's reason
CARRY_EASE = 0.5
# cm within which a free foot counts as on the input's path already (``_follow_input_path``):
# the IK makes a knee an exact hinge and eases a straight one, so even its smallest share
# moved a leg the restyle had left alone (a style served as performed: 1e-5 where it
# passes through to 5e-8).
PATH_AT = 0.01


@dataclass(eq=False)
class LockJob:
    """One lock's output frames t0 .. t0+n-1 from ``FootLock.plan`` to ``solve_lock_jobs``:
    input ``roots`` (n, 3), input and restyled rotations (n, J, 4), lock ``weights`` (n, 2),
    which feet are ``down`` for the pelvis (n, 2), the ``floor`` (n,), the restyle's ``mix``
    (n,) or None, and the input's feet ``own`` (n, ankle/ball, foot, xyz) as pushed. Solving
    fills in ``new_roots`` (the pelvis height and the pace set) and ``result``, the locked
    rotations."""

    lock: FootLock
    t0: int
    roots: np.ndarray
    inputs: np.ndarray
    outputs: np.ndarray
    weights: np.ndarray
    down: np.ndarray
    floor: np.ndarray
    mix: np.ndarray | None = None
    own: np.ndarray | None = None
    new_roots: np.ndarray | None = None
    result: np.ndarray | None = None


def solve_lock_jobs(jobs: list[LockJob]) -> None:
    """Many locks' jobs (the daemon: every performer's frame of this tick) in one vectorised
    pass, each frame with its own performer's proportions: the pelvis height and stance
    (each lock's state advanced in order), the arms' swing, the knees' bend and the hips' bob
    (``GaitAmplitude``), the lock of planted feet, then the floor (see the module
    docstring). Run per lock, numpy's per-call cost was 55x the work
    (``bench_daemon.py footlock``). Each job is solved once, in the order of its frames."""
    if not jobs:
        return
    rows = _Rows(jobs)
    _advance(rows)
    _scale_amplitudes(rows)
    _carry_free_feet(rows)
    _follow_input_path(rows)
    for with_stance in (False, True):  # the two kinds of target: one pass each
        _lock_planted(rows, np.flatnonzero((rows.weights.max(axis=1) > 0) & (rows.with_stance == with_stance)))
    _keep_above_floor(rows)
    for job, (lo, hi) in zip(jobs, rows.spans):
        job.new_roots, job.result = rows.new_roots[lo:hi], rows.result[lo:hi]


class _Rows:
    """Every job's frames stacked into one set of rows, the arrays the vectorised passes
    work on (``result`` is written in place), with each row's performer's proportions."""

    def __init__(self, jobs: list[LockJob]):
        self.jobs = jobs
        sizes = [len(j.roots) for j in jobs]
        ends = np.cumsum(sizes)
        self.spans = list(zip((ends - sizes).tolist(), ends.tolist()))
        stack = (lambda f: f(jobs[0])) if len(jobs) == 1 else (lambda f: np.concatenate([f(j) for j in jobs]))
        self.roots, self.inputs, self.outputs = stack(lambda j: j.roots), stack(lambda j: j.inputs), \
            stack(lambda j: j.outputs)
        self.weights, self.floor, self.own_feet = stack(lambda j: j.weights), stack(lambda j: j.floor), \
            stack(lambda j: j.own)
        self.down = stack(lambda j: j.down)
        # (J, 3) for one lock, (rows, J, 3) for several (leg_chain takes either)
        self.offsets = jobs[0].lock.offsets if len(jobs) == 1 else \
            np.repeat(np.stack([j.lock.offsets for j in jobs]), sizes, axis=0)
        self.ankle_rest = np.repeat([j.lock.ankle_rest for j in jobs], sizes)
        self.with_stance = np.repeat([j.lock.stance.cap > 0 for j in jobs], sizes)
        self.on_path = np.repeat([j.lock.settings.swing_path for j in jobs], sizes)  # ``swing_path``
        self.result = self.outputs.copy()  # the caller's outputs stay as they are
        self.new_roots = self.own = self.stance = None  # set by ``_advance``
        self.feet_shift = np.zeros((len(self.roots), 2, 2))  # ``Pace``: each foot's (x, z) ...
        self.carry = np.zeros((len(self.roots), 2, 2))  # ...and how far it lags the body's

    def offsets_of(self, rows: np.ndarray) -> np.ndarray:
        return self.offsets if self.offsets.ndim == 2 else self.offsets[rows]


def _scale_amplitudes(rows: _Rows) -> None:
    """Each lock's ``GaitAmplitude`` on its rows: the arms' swing and the knees' bend
    (``result``; the pelvis and the stance read ``outputs``) and the hips' bob (``new_roots``,
    set by ``_advance``), before the legs are solved from them; one vectorised pass where
    every lock has one frame (the daemon's tick)."""
    jobs = rows.jobs
    if len(jobs) > 1 and len(rows.roots) == len(jobs):
        shown = [1.0 if job.mix is None else float(job.mix[0]) for job in jobs]
        heights = rows.new_roots[:, 1].copy()
        amplitude_frames([job.lock.amplitude for job in jobs], rows.roots, rows.inputs, rows.result, heights, shown,
                         rows.offsets)
        rows.new_roots[:, 1] = heights
        return
    for job, (lo, hi) in zip(jobs, rows.spans):
        swung, bobbed = job.lock.amplitude.apply(job.roots, job.inputs, rows.result[lo:hi], rows.new_roots[lo:hi, 1],
                                                 job.mix, rows.offsets_of(slice(lo, hi)))
        if swung is not None:
            rows.result[lo:hi] = swung
        if bobbed is not None:
            rows.new_roots[lo:hi, 1] = bobbed


def _advance(rows: _Rows) -> None:
    """Where the restyled feet stand against the input's (the input's as they were pushed,
    the restyle's legs in one forward kinematics call for every row): the ankles' height
    gap sets the pelvis, the rest the stance (``--feet stance``); each lock's state moves
    on, in order."""
    jobs = rows.jobs
    own = (rows.own_feet[:, 0], rows.own_feet[:, 1])
    if len(jobs) == 1:  # one lock (one performer, or a clip): its own path, floats for one frame
        restyled = jobs[0].lock.feet(rows.roots, rows.outputs)
    else:
        pos_out, _, _ = leg_chain(rows.roots, rows.outputs, rows.offsets)
        restyled = (pos_out[:, :, 2], pos_out[:, :, 3])
    rows.own = own  # the input's ankles and balls: the lock's targets and the floor's ceiling
    gap = restyled[0][..., 1] - own[0][..., 1]  # (rows, 2)
    rows.new_roots = rows.roots.copy()
    rows.stance = np.zeros((len(rows.roots), 2, 3))
    down = rows.down
    if len(jobs) > 1 and len(rows.roots) == len(jobs):
        _advance_one_frame_each(rows, restyled, gap)
        return
    for job, (lo, hi) in zip(jobs, rows.spans):
        lock = job.lock
        rows.new_roots[lo:hi, 1] -= lock.pelvis.drops(np.where(down[lo:hi], gap[lo:hi], 0.0), down[lo:hi])
        stance = lock.stance.track(job.t0, (own[0][lo:hi], own[1][lo:hi]),
                                   (restyled[0][lo:hi], restyled[1][lo:hi]), job.weights, job.mix, job.roots)
        if stance is not None:
            rows.stance[lo:hi] = stance
        pace = lock.pace.track(job.roots, own[0][lo:hi], job.weights, job.mix)
        if pace is not None:
            body, feet = pace
            rows.new_roots[lo:hi, 0] -= body[:, 0]
            rows.new_roots[lo:hi, 2] -= body[:, 1]
            rows.feet_shift[lo:hi] = feet
            rows.carry[lo:hi] = body[:, None] - feet
        lock.locked_frames += int(np.count_nonzero(job.weights >= 1.0))


def _advance_one_frame_each(rows: _Rows, restyled: tuple, gap: np.ndarray) -> None:
    """``_advance`` where every lock has one frame (the daemon's tick): the stances'
    targets in one pass for all (``stance_targets``, each row with its lock's settings),
    then each lock's recurrences step on Python floats read out of the rows in one go, and
    their results go back into the rows in one go. Why: per lock, numpy's slicing and small
    arrays cost more than the recurrences' own arithmetic (a sampling profile of 64
    performers: that loop was 11 % of the process's time). ``solve_lock_jobs`` for 64
    locks, one frame each (min of 7 rounds, interleaved with the per-lock loop in one
    process): 4.8 -> 3.6 ms a tick with ``--feet input``, 8.9 -> 4.3 ms with the stance,
    the results bit for bit the same."""
    jobs = rows.jobs
    gaps, down = np.where(rows.down, gap, 0.0).tolist(), rows.down.tolist()
    xz, weights = rows.roots[:, [0, 2]].tolist(), rows.weights.tolist()
    ankles_xz = rows.own[0][:, :, [0, 2]].tolist()
    shown = [1.0 if job.mix is None else float(job.mix[0]) for job in jobs]
    at = [i for i, job in enumerate(jobs) if job.lock.stance.cap > 0]  # the rows with a stance (--feet stance)
    if at:
        stances = [jobs[i].lock.stance for i in at]
        per_row = np.array([[s.cap, s.turn_cap, s.turn_unsure, s.turn_sure] for s in stances])
        wanted, sure = stance_targets((rows.own[0][at], rows.own[1][at]), (restyled[0][at], restyled[1][at]),
                                      per_row[:, 0, None, None], per_row[:, 1, None, None], per_row[:, 2, None],
                                      per_row[:, 3, None])
        wanted, sure = wanted.tolist(), sure.tolist()
        rows.stance[at] = [stance.follow(jobs[i].t0, [wanted[k]], [weights[i]], [sure[k]], [shown[i]], [xz[i]])[0]
                           for k, (i, stance) in enumerate(zip(at, stances))]
    drops, paced, body, feet = [], [], [], []
    for i, job in enumerate(jobs):
        lock = job.lock
        drops.append(lock.pelvis.drop_of_one_frame(gaps[i], down[i]))
        shift = lock.pace.track_one_frame(*xz[i], ankles_xz[i], *weights[i], shown[i])
        if shift is not None:
            paced.append(i)
            body.append(shift[0])
            feet.append(shift[1])
        lock.locked_frames += (weights[i][0] >= 1.0) + (weights[i][1] >= 1.0)
    rows.new_roots[:, 1] -= drops
    if paced:
        body, feet = np.array(body), np.array(feet)
        rows.new_roots[paced, 0] -= body[:, 0]
        rows.new_roots[paced, 2] -= body[:, 1]
        rows.feet_shift[paced] = feet
        rows.carry[paced] = body[:, None] - feet


def _carry_free_feet(rows: _Rows) -> None:
    """``Pace``: a foot not fully locked goes where its (restyled) leg puts it, moved by how
    far its own shift lags the body's (the leg IK, the foot keeping its world rotation), in
    by the carry needed over CARRY_EASE, as the floor step eases its lift. (Not on the
    input's path, ``_follow_input_path``.)"""
    size = np.linalg.norm(rows.carry, axis=-1)  # (rows, 2)
    need = (rows.weights < 1.0) & (size > 0.0) & ~rows.on_path[:, None]
    at = np.flatnonzero(need.any(axis=1))
    if not len(at):
        return
    chain = leg_chain(rows.new_roots[at], rows.result[at], rows.offsets_of(at))
    target = chain[0][:, :, 2].copy()
    target[..., [0, 2]] += rows.carry[at]
    _ease_free_legs(rows, at, chain, target, np.where(need[at], np.clip(size[at] / CARRY_EASE, 0.0, 1.0), 0.0))


def _follow_input_path(rows: _Rows) -> None:
    """``ContactSettings.swing_path``: a foot not fully locked goes along the input's own
    ankle path, less its ``Pace`` shift and lowered as far as the hips were (the pelvis
    height), by the leg IK: the knee bends the way the restyled one points and the foot
    keeps its restyled world rotation; in by the distance to go beyond PATH_AT over
    CARRY_EASE, so that a leg already there is left as it is. The lock then blends it onto
    the input's ankle by its weight (``_lock_planted``), as for any other foot."""
    need = (rows.weights < 1.0) & rows.on_path[:, None]
    at = np.flatnonzero(need.any(axis=1))
    if not len(at):
        return
    chain = leg_chain(rows.new_roots[at], rows.result[at], rows.offsets_of(at))
    target = rows.own[0][at].copy()  # the input's ankles
    target[..., [0, 2]] -= rows.feet_shift[at]
    target[..., 1] += (rows.new_roots[at, 1] - rows.roots[at, 1])[:, None]
    to_go = np.linalg.norm(target - chain[0][:, :, 2], axis=-1)
    _ease_free_legs(rows, at, chain, target, np.where(need[at], np.clip((to_go - PATH_AT) / CARRY_EASE, 0.0, 1.0), 0.0))


def _ease_free_legs(rows: _Rows, at: np.ndarray, chain: tuple, target: np.ndarray, eased: np.ndarray) -> None:
    """Rows ``at``: each leg by the leg IK onto its ankle ``target`` (rows, 2, 3), the knee
    bent the way the restyled one points and the foot keeping its world rotation (``chain``:
    ``leg_chain`` of the rows as they are), slerped in by ``eased`` (rows, 2)."""
    outputs = rows.result[at]
    solved = solve_legs(rows.new_roots[at], outputs, rows.offsets_of(at), target, chain[1][:, :, 2], chain)
    legs = LEG_INDEX[:, :3]
    weight = np.broadcast_to(eased[:, :, None], solved.shape[:-1])
    rows.result[at[:, None, None], legs[None]] = rot.slerp(outputs[:, legs], solved, weight)


def _lock_planted(rows: _Rows, at: np.ndarray) -> None:
    """Rows ``at``, where a lock weight is above 0: the leg IK onto the input's ankle (or
    beside it, with the stance; less the foot's ``Pace`` shift), the foot turned as the
    input's, the knee in its restyled plane, slerped with the restyled (and carried) leg by
    the weight."""
    if not len(at):
        return
    offsets, inputs, outputs = rows.offsets_of(at), rows.inputs[at], rows.result[at]
    pos_in, world_in, _ = leg_chain(rows.roots[at], inputs, offsets)
    ankle, foot = pos_in[:, :, 2].copy(), world_in[:, :, 2]  # the input's own
    ankle[..., [0, 2]] -= rows.feet_shift[at]
    if rows.with_stance[at[0]]:  # beside them, turned as restyled
        stance = rows.stance[at]
        ankle = ankle + stance[:, :, :2] @ np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        foot = rot.multiply(rot.exp_map(stance[:, :, 2:] * np.array([0.0, 1.0, 0.0])), foot)
    solved = solve_legs(rows.new_roots[at], outputs, offsets, ankle, foot)
    target = np.concatenate([solved, inputs[:, LEG_INDEX[:, 3:]]], axis=2)  # toes as the input's
    weight = np.broadcast_to(rows.weights[at][:, :, None], target.shape[:-1])
    rows.result[at[:, None, None], LEG_INDEX[None]] = rot.slerp(outputs[:, LEG_INDEX], target, weight)


def _keep_above_floor(rows: _Rows) -> None:
    """A foot in the air can go through the floor the input's foot cleared: a restyled
    leg straighter than the input's, a foot pitched further down, or (most, measured
    2.7 cm at the 99th percentile on held-out clips without this step) the lowered
    pelvis. Where the ankle would go below its standing height over the floor, or the
    ball below the floor, the leg IK lifts the ankle (the foot keeps its rotation, the
    knee its plane) until both clear it (a lift under FLOOR_LIFT_EASE only in part: up to
    1.25 mm short), through a soft edge (``_soft_floor``), never
    higher than the input's own foot there (``own``: its ankles and balls). Near the
    floor the input's own clearance counts too (``kept_clearance``): a heel the input
    holds 2 cm up as it lands is not put down on the floor early and dragged there.
    Lifting the ankle rather than pitching the foot up: a foot pointing down needs a large turn for a
    small lift (measured: an 8-degree pop in one frame). A fully locked foot (weight 1) is
    the input's own, above the floor by definition, and is skipped: most frames of a
    stream."""
    free = rows.weights < 1.0
    at = np.flatnonzero(free.any(axis=1))
    if not len(at):
        return
    everywhere = leg_chain(rows.new_roots[at], rows.result[at], rows.offsets_of(at))
    pos = everywhere[0]
    floor, rest = rows.floor[at, None], rows.ankle_rest[at, None]
    own_ankle, own_ball = rows.own[0][at, :, 1], rows.own[1][at, :, 1]
    ankle_floor = np.maximum(np.minimum(floor + rest, own_ankle), kept_clearance(own_ankle, floor + rest))
    ball_floor = np.maximum(np.minimum(floor, own_ball), kept_clearance(own_ball, floor))
    near = free[at] & ((pos[:, :, 2, 1] < ankle_floor + FLOOR_MARGIN) | (pos[:, :, 3, 1] < ball_floor + FLOOR_MARGIN))
    keep = near.any(axis=1)
    at, near, ankle_floor, ball_floor = at[keep], near[keep], ankle_floor[keep], ball_floor[keep]
    own_ankle, own_ball = own_ankle[keep], own_ball[keep]
    if not len(at):
        return
    roots, outputs, offsets = rows.new_roots[at], rows.result[at], rows.offsets_of(at)
    chain = tuple(x[keep] for x in everywhere)
    pos, world, _ = chain
    up = np.maximum(
        _soft_floor(pos[:, :, 2, 1], ankle_floor, own_ankle) - pos[:, :, 2, 1],
        _soft_floor(pos[:, :, 3, 1], ball_floor, own_ball) - pos[:, :, 3, 1])
    lift = near & (up > 0)
    if not lift.any():
        return
    target = pos[:, :, 2].copy()
    target[..., 1] += up
    solved = solve_legs(roots, outputs, offsets, target, world[:, :, 2], chain)
    legs = LEG_INDEX[:, :3]
    # In by the lift needed, not at once: the solve moves a nearly straight knee even for
    # a lift of nothing (the hinge, the soft reach), and a leg switched in and out jumped.
    eased = np.where(lift, np.clip(up / FLOOR_LIFT_EASE, 0.0, 1.0), 0.0)
    weight = np.broadcast_to(eased[:, :, None], solved.shape[:-1])
    rows.result[at[:, None, None], legs[None]] = rot.slerp(outputs[:, legs], solved, weight)


def kept_clearance(own: np.ndarray, base: np.ndarray) -> np.ndarray:
    """The height a foot joint in the air may not go below for the input's own height
    ``own`` over ``base`` (its height standing on the floor): the input's clearance
    ``own - base``, saturating smoothly at CLEARANCE_BAND (band * tanh(clearance / band)),
    less CLEARANCE_SLACK. Smoothly: capped with a corner (min(clearance, band)), the floor
    stopped dead as a lifting foot passed the band, and a held-out walk's shuffling step
    popped a knee (1.64x the input's largest jerk)."""
    clearance = np.maximum(own - base, 0.0)
    return base + CLEARANCE_BAND * np.tanh(clearance / CLEARANCE_BAND) - CLEARANCE_SLACK


def _soft_floor(height: np.ndarray, floor: np.ndarray, own: np.ndarray) -> np.ndarray:
    """A floor with a soft edge: heights FLOOR_MARGIN or more above ``floor`` unchanged,
    anything below the floor put on it, and in between a quadratic that meets both with
    the same slope; never raised above ``own``, the input's own height there (so a foot
    the lock put where the input's is stays there). A hard clamp's corner in the foot's
    path showed as jerk (all joints 1.096x the input's, feet 1.27x; 1.087x and 1.24x with
    the edge)."""
    u = np.clip((height - floor) / FLOOR_MARGIN, -1.0, 1.0)
    eased = np.where(height - floor >= FLOOR_MARGIN, height, floor + FLOOR_MARGIN * (u + 1.0) ** 2 / 4.0)
    return np.where(height >= own, height, np.minimum(eased, own))
