"""The foot lock (motion/footlock.py): contacts with hysteresis, a planted foot kept where
the input put it to within a millimetre, bone lengths kept, the same result streamed a
frame at a time as for a whole clip, and nothing done where no foot is planted."""

from __future__ import annotations

import numpy as np
import pytest

from stylecast.motion import rotations as rot
from stylecast.motion.footlock import LEGS, ContactSettings, FootLock, _hysteresis, leg_chain
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default

J = len(HUMANOID_BONES)
SK = humanoid_skeleton_default()


def stepping(frames: int = 240):
    """A standing figure lifting its right foot for half a second every second: the left
    foot stays planted, the right one plants and lifts. Returns (roots, rotations)."""
    t = np.arange(frames) / 60.0
    q = np.tile(rot.identity((J,)), (frames, 1, 1))
    lift = np.clip(np.sin(2 * np.pi * t), 0, None)  # half of each second up
    right_up, right_knee = HUMANOID_BONES.index("RightUpperLeg"), HUMANOID_BONES.index("RightLowerLeg")
    q[:, right_up] = rot.exp_map(np.stack([-0.9 * lift, 0 * t, 0 * t], -1))  # thigh forward
    q[:, right_knee] = rot.exp_map(np.stack([1.4 * lift, 0 * t, 0 * t], -1))  # knee bent back
    # The standing knees are soft (a straight leg cannot reach any further when the
    # restyled hips move away from its foot).
    for side, sign in (("Left", 1.0), ("Right", 1.0)):
        for bone, angle in (("UpperLeg", -0.2), ("LowerLeg", 0.4)):
            j = HUMANOID_BONES.index(f"{side}{bone}")
            q[:, j] = rot.multiply(q[:, j], rot.exp_map(np.array([sign * angle, 0.0, 0.0])))
    # the ground: default humanoid legs hang 82 cm and the ball sits a foot-height lower
    roots = np.stack([0 * t, 100.0 + 0 * t, 0 * t], -1)
    return roots, q


def restyled(q: np.ndarray, degrees: float = 12.0) -> np.ndarray:
    """A 'restyle' that leans the hips and bends both legs differently (feet would slide)."""
    out = q.copy()
    wobble = np.radians(degrees) * np.sin(np.arange(len(q)) / 9.0)
    for bone, axis in (("Hips", 0), ("LeftUpperLeg", 0), ("LeftLowerLeg", 0), ("RightUpperLeg", 2)):
        v = np.zeros((len(q), 3))
        v[:, axis] = wobble
        j = HUMANOID_BONES.index(bone)
        out[:, j] = rot.multiply(out[:, j], rot.exp_map(v))
    return out


def test_contacts_follow_the_feet_with_hysteresis():
    roots, q = stepping()
    contacts = FootLock(SK).push(roots, q)
    assert not contacts[0].any()  # a stream's first frame has no speed yet
    assert contacts[1:, 0].all()  # the left foot never leaves the floor
    right = contacts[:, 1]
    assert 0.3 < right.mean() < 0.7  # planted about half the time
    changes = np.count_nonzero(np.diff(right.astype(int)))
    assert changes <= 2 * 4  # once down and once up per step (4 steps): no flicker


def test_hysteresis_holds_between_the_two_thresholds():
    plant = np.array([[0], [1], [0], [0], [0], [0]], bool)
    release = np.array([[0], [0], [0], [0], [1], [0]], bool)
    state = _hysteresis(plant, release, np.array([False]))[:, 0]
    assert state.tolist() == [False, True, True, True, False, False]


def test_a_planted_foot_stays_within_a_millimetre_and_legs_keep_their_length():
    roots, q = stepping()
    out_in = restyled(q)
    lock = FootLock(SK)
    contacts = lock.push(roots, q)
    locked_roots, locked = lock.apply(0, roots, q, out_in)
    p_in, _, _ = leg_chain(roots, q, SK.offsets)
    p_raw, _, _ = leg_chain(roots, out_in, SK.offsets)
    p_out, _, _ = leg_chain(locked_roots, locked, SK.offsets)
    err_raw = np.linalg.norm(p_raw[:, :, 2] - p_in[:, :, 2], axis=-1)[contacts]
    err = np.linalg.norm(p_out[:, :, 2] - p_in[:, :, 2], axis=-1)[contacts]
    assert err_raw.max() > 5.0  # without the lock the planted foot wanders by centimetres
    assert err.max() < 0.1  # with it: within a millimetre (positions are in cm)
    for side, (upper, lower, foot, toes) in enumerate(LEGS):
        for k, bone in ((1, lower), (2, foot)):
            length = np.linalg.norm(p_out[:, side, k] - p_out[:, side, k - 1], axis=-1)
            np.testing.assert_allclose(length, np.linalg.norm(SK.offsets[bone]), atol=1e-9)
    # the ball of the foot follows as well (foot orientation and toes from the input)
    assert np.linalg.norm(p_out[:, :, 3] - p_in[:, :, 3], axis=-1)[contacts].max() < 0.1


def test_streaming_a_frame_at_a_time_equals_the_whole_clip():
    roots, q = stepping(180)
    out_in = restyled(q)
    whole = FootLock(SK, ramp=4)
    whole.push(roots, q)
    expected_roots, expected = whole.apply(0, roots, q, out_in)
    live = FootLock(SK, ramp=4)
    got, got_roots = [], []
    for t in range(len(q)):
        live.push(roots[t:t + 1], q[t:t + 1])
        k = t - 4
        if k >= 0:
            r, frame = live.apply(k, roots[k:k + 1], q[k:k + 1], out_in[k:k + 1])
            got.append(frame[0])
            got_roots.append(r[0])
    assert rot.angle_between(np.array(got), expected[:len(got)]).max() < 1e-9
    np.testing.assert_allclose(np.array(got_roots), expected_roots[:len(got)], atol=1e-9)
    assert np.ptp(expected_roots[:, 1]) > 0.5  # the pelvis height really moved


def test_nothing_changes_where_no_foot_is_planted_or_near_the_floor():
    roots, q = stepping(120)
    roots[10:, 1] += 50.0  # after 10 frames on the floor, jumped: both feet half a metre up...
    roots[:, 2] = 5.0 * np.arange(len(roots))  # ...and moving fast all along: never planted
    lock = FootLock(SK)
    assert not lock.push(roots, q).any()
    out_in = restyled(q)
    new_roots, out = lock.apply(0, roots, q, out_in)
    np.testing.assert_array_equal(new_roots, roots)
    np.testing.assert_array_equal(out[10:], out_in[10:])


def crouched(q: np.ndarray, degrees: float = 15.0) -> np.ndarray:
    """A 'restyle' into a lower stance: both thighs forward by an angle and both knees
    bent back by twice that, so each ankle ends up nearly straight above where the input
    put it (thigh and shin are about as long), centimetres up (the root did not move)."""
    out = q.copy()
    a = np.radians(degrees)
    for side in ("Left", "Right"):
        for bone, angle in (("UpperLeg", -a), ("LowerLeg", 2 * a)):
            j = HUMANOID_BONES.index(f"{side}{bone}")
            out[:, j] = rot.multiply(out[:, j], rot.exp_map(np.array([angle, 0.0, 0.0])))
    return out


def knee_angles(roots, rotations):
    p, _, _ = leg_chain(roots, rotations, SK.offsets)
    thigh, shin = p[:, :, 0] - p[:, :, 1], p[:, :, 2] - p[:, :, 1]
    cos = np.sum(thigh * shin, -1) / np.linalg.norm(thigh, axis=-1) / np.linalg.norm(shin, axis=-1)
    return np.degrees(np.arccos(np.clip(cos, -1, 1)))


def test_the_pelvis_lowers_so_a_restyled_knee_bend_stands_on_the_planted_feet():
    roots, q = stepping(240)
    standing = np.tile(q[:1], (240, 1, 1))  # both feet planted all the time
    roots = np.tile(roots[:1], (240, 1))
    out_in = crouched(standing)
    p_in, _, _ = leg_chain(roots, standing, SK.offsets)
    p_raw, _, _ = leg_chain(roots, out_in, SK.offsets)
    gap = float(np.mean(p_raw[-1, :, 2, 1] - p_in[-1, :, 2, 1]))
    assert gap > 3.0  # the crouch lifts both ankles off the floor

    def lock(settings=ContactSettings()):
        fl = FootLock(SK, settings=settings)
        contacts = fl.push(roots, standing)
        return contacts, *fl.apply(0, roots, standing, out_in)

    contacts, new_roots, locked = lock()
    _, flat_roots, straightened = lock(ContactSettings(pelvis_tau=0))
    np.testing.assert_array_equal(flat_roots, roots)  # off: the root passes through
    settled = slice(120, None)
    # The hips come down by the gap, only vertically, and the restyled knee bend is kept
    # (without the adjustment the IK straightens the legs back to the input's).
    np.testing.assert_allclose(roots[settled, 1] - new_roots[settled, 1], gap, atol=0.05)
    np.testing.assert_array_equal(new_roots[:, [0, 2]], roots[:, [0, 2]])
    bend_in, bend_restyled = knee_angles(roots, standing), knee_angles(roots, out_in)
    bend_locked, bend_flat = knee_angles(new_roots, locked), knee_angles(flat_roots, straightened)
    assert np.abs(bend_locked[settled] - bend_restyled[settled]).max() < 0.5  # degrees
    assert np.abs(bend_flat[settled] - bend_in[settled]).max() < 0.5
    assert (bend_in - bend_restyled)[settled].min() > 20.0  # the two really differ
    p_out, _, _ = leg_chain(new_roots, locked, SK.offsets)
    assert np.linalg.norm(p_out[:, :, 2] - p_in[:, :, 2], axis=-1)[contacts].max() < 0.1  # feet planted
    # The hips settle smoothly from the stream's start (no step in height or speed).
    assert np.abs(np.diff(new_roots[:, 1], 2)).max() < 0.1 * gap


def test_an_unchanged_output_leaves_the_pelvis_and_legs_alone():
    roots, q = stepping(180)
    lock = FootLock(SK)
    lock.push(roots, q)
    new_roots, out = lock.apply(0, roots, q, q)
    np.testing.assert_allclose(new_roots, roots, atol=1e-9)
    assert rot.angle_between(out, q).max() < 1e-6


def test_the_pelvis_never_moves_further_than_its_cap():
    roots, q = stepping(240)
    standing = np.tile(q[:1], (240, 1, 1))
    roots = np.tile(roots[:1], (240, 1))
    fl = FootLock(SK, settings=ContactSettings(pelvis_cap=1.0))
    fl.push(roots, standing)
    new_roots, _ = fl.apply(0, roots, standing, crouched(standing, 40.0))
    drop = roots[:, 1] - new_roots[:, 1]
    assert drop.max() <= 1.0 + 1e-9 and drop[-1] > 0.99


def test_a_foot_in_the_air_is_kept_above_the_floor():
    """Standing, then gliding off (no foot planted): the restyle crouches while standing,
    so the pelvis comes down, then gives the input's legs back. Held at the lowered height
    through the glide, the input's legs would push the feet through the floor."""
    roots, q = stepping(240)
    q = np.tile(q[:1], (240, 1, 1))
    roots = np.tile(roots[:1], (240, 1))
    roots[120:, 2] = 5.0 * np.arange(120)  # from frame 120 on: moving fast, nothing planted
    restyled_ = q.copy()
    restyled_[:130] = crouched(q[:130])  # crouched until the feet are off
    lock = FootLock(SK)
    contacts = lock.push(roots, q)
    assert contacts[1:110].all() and not contacts[125:].any()
    new_roots, out = lock.apply(0, roots, q, restyled_)
    assert (roots[200:, 1] - new_roots[200:, 1]).min() > 5.0  # the pelvis height is held
    p_in, _, _ = leg_chain(roots, q, SK.offsets)
    p_raw, _, _ = leg_chain(new_roots, restyled_, SK.offsets)
    p_out, _, _ = leg_chain(new_roots, out, SK.offsets)
    floor = np.minimum.accumulate(p_in[:, :, 3, 1].min(axis=1))  # the lowest ball so far
    limit = np.minimum(floor[:, None] + lock._ankle_rest, p_in[:, :, 2, 1])
    assert (limit - p_raw[:, :, 2, 1]).max() > 3.0  # without the floor: centimetres under
    assert (limit - p_out[:, :, 2, 1]).max() < 1e-6  # with it: nowhere below
    lengths = np.linalg.norm(p_out[:, :, 2] - p_out[:, :, 1], axis=-1)
    np.testing.assert_allclose(lengths, np.linalg.norm(SK.offsets[LEGS[0][2]]), atol=1e-9)


def test_a_foot_pitched_into_the_floor_is_lifted_onto_it():
    roots, q = stepping(120)
    q = np.tile(q[:1], (120, 1, 1))  # standing pose, gliding: nothing planted
    roots = np.tile(roots[:1], (120, 1))
    roots[:, 2] = 5.0 * np.arange(120)
    toes_down = q.copy()
    for side in ("Left", "Right"):
        j = HUMANOID_BONES.index(f"{side}Foot")
        toes_down[:, j] = rot.multiply(q[:, j], rot.exp_map(np.array([0.5, 0.0, 0.0])))
    lock = FootLock(SK)
    assert not lock.push(roots, q).any()
    new_roots, out = lock.apply(0, roots, q, toes_down)
    p_in, w_in, _ = leg_chain(roots, q, SK.offsets)
    p_raw, w_raw, _ = leg_chain(new_roots, toes_down, SK.offsets)
    p_out, w_out, _ = leg_chain(new_roots, out, SK.offsets)
    floor = p_in[:, :, 3, 1].min()
    assert (floor - p_raw[:, :, 3, 1]).min() > 2.0  # the balls go centimetres under
    np.testing.assert_allclose(p_out[:, :, 3, 1], floor, atol=1e-6)  # lifted onto the floor...
    assert rot.angle_between(w_out[:, :, 2], w_raw[:, :, 2]).max() < 1e-6  # ...the foot turned as restyled
    np.testing.assert_allclose(p_out[:, :, 2, [0, 2]], p_raw[:, :, 2, [0, 2]], atol=1e-6)  # straight up


def test_the_soft_floor_is_continuous_with_its_slope_and_never_lifts_above_the_input():
    from stylecast.motion.footlock import FLOOR_MARGIN, _soft_floor

    h = np.linspace(-3.0, 3.0, 6001) * FLOOR_MARGIN
    zero, high = np.zeros_like(h), np.full_like(h, 100.0)
    eased = _soft_floor(h, zero, high)
    assert eased.min() >= 0.0  # nothing below the floor
    np.testing.assert_array_equal(eased[h >= FLOOR_MARGIN], h[h >= FLOOR_MARGIN])  # untouched above the edge
    slope = np.diff(eased) / np.diff(h)
    assert np.all(np.diff(eased) >= 0) and np.abs(np.diff(slope)).max() < 0.01  # no corner
    own = np.full_like(h, 0.1 * FLOOR_MARGIN)  # the input's own foot lower than the edge
    capped = _soft_floor(h, zero, own)
    assert np.all(capped[h < own] <= own[h < own] + 1e-12)
    np.testing.assert_array_equal(capped[h >= own], h[h >= own])


def test_the_ramp_never_looks_further_ahead_than_the_stream_delay():
    assert FootLock.for_stream(SK, delay=1).ramp == 1
    assert FootLock.for_stream(SK, delay=60).ramp == ContactSettings.ramp


def test_a_rig_that_is_not_the_humanoid_is_refused():
    from stylecast.motion.skeleton import Skeleton

    with pytest.raises(ValueError):
        FootLock(Skeleton(("a", "b"), (-1, 0), np.zeros((2, 3))))


def test_the_one_frame_float_path_equals_the_array_path():
    from stylecast.motion.footlock import _feet_of_one_frame

    roots, q = stepping(30)
    q = restyled(q)
    lock = FootLock(SK)
    pos, _, _ = leg_chain(roots, q, SK.offsets)
    for t in range(30):
        ankle, ball = _feet_of_one_frame(roots[t], q[t], lock._leg_offsets)
        np.testing.assert_allclose(ankle, pos[t, :, 2], atol=1e-9)
        np.testing.assert_allclose(ball, pos[t, :, 3], atol=1e-9)
