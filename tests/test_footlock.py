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
    locked = lock.apply(0, roots, q, out_in)
    p_in, _, _ = leg_chain(roots, q, SK.offsets)
    p_raw, _, _ = leg_chain(roots, out_in, SK.offsets)
    p_out, _, _ = leg_chain(roots, locked, SK.offsets)
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
    expected = whole.apply(0, roots, q, out_in)
    live = FootLock(SK, ramp=4)
    got = []
    for t in range(len(q)):
        live.push(roots[t:t + 1], q[t:t + 1])
        k = t - 4
        if k >= 0:
            got.append(live.apply(k, roots[k:k + 1], q[k:k + 1], out_in[k:k + 1])[0])
    assert rot.angle_between(np.array(got), expected[:len(got)]).max() < 1e-9


def test_nothing_changes_where_no_foot_is_planted():
    roots, q = stepping(120)
    roots = roots + np.array([0.0, 50.0, 0.0])  # jumped: both feet half a metre up...
    roots[:, 2] = 5.0 * np.arange(len(roots))  # ...and moving fast
    lock = FootLock(SK)
    lock.push(roots, q)
    out_in = restyled(q)
    assert np.array_equal(lock.apply(0, roots, q, out_in), out_in)


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
