"""The foot lock's contacts and timing (motion/footlock/contacts.py, lock.py): contacts with
hysteresis, a lock that sets in and lets go with zero slope over its own frames and reads no
further ahead than the stream's delay, and contacts detected and locks planned alike for
performers in one call and each alone."""

from __future__ import annotations

import numpy as np
import pytest

from stylecast.motion import rotations as rot
from stylecast.motion.footlock import ContactSettings, FootLock, leg_chain, lock_kernel, plan_locks, push_frames
from stylecast.motion.footlock.contacts import hysteresis, lock_weights
from stylecast.motion.humanoid import HUMANOID_BONES
from tests.footlock_motion import SK, restyled, stepping


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
    state = hysteresis(plant, release, np.array([False]))[:, 0]
    assert state.tolist() == [False, True, True, True, False, False]


def test_a_lock_reads_no_further_ahead_than_the_stream_delay():
    short, long = FootLock.for_stream(SK, delay=1), FootLock.for_stream(SK, delay=60)
    assert (short.sight, short.ramp) == (1, ContactSettings.ramp)
    assert long.sight == long.ramp == ContactSettings.ramp


def test_a_lock_that_sees_one_frame_ahead_sets_in_as_the_foot_comes_down():
    """``--latency low`` (delay 1): the lock sets in as the stepping foot comes down
    (``approach``) and meets the contact's own weight without a step; the known-bad lock
    that sets in over the one frame it sees (the previous release's) waits for the contact
    and snaps in, 0 -> 0.5 -> 1."""
    roots, q = stepping(240)
    foreseeing, snapping, full = FootLock(SK, sight=1), FootLock(SK, ramp=1), FootLock(SK)
    right = [lock.push(roots, q)[:, 1] for lock in (foreseeing, snapping, full)][0]
    start = int(np.flatnonzero(right[1:] & ~right[:-1])[0]) + 1  # the right foot's first touch-down
    w, w_snap, w_full = (lock.weights(0, 236)[:, 1] for lock in (foreseeing, snapping, full))
    assert w_snap[start - 2] == 0.0 and w_snap[start - 1] == 0.5
    assert w[start - 3] > 0.4 and np.all(np.diff(w[start - 6:start + 1]) > 0)  # already on its way
    assert w[start] == 1.0
    np.testing.assert_array_equal(w[start - 1:start + 20], w_full[start - 1:start + 20])  # from the seen frame on
    steepest = lambda weights: np.abs(np.diff(weights, 2)).max()
    assert steepest(w) < 0.3 and steepest(w_snap) > 0.45
    assert np.abs(np.diff(w)).max() <= 0.33  # slew-limited: neither foreseen nor let go in a leap
    lift = start + int(np.argmin(right[start:]))
    land = lift + int(np.argmax(right[lift:]))
    assert np.count_nonzero(w[lift:land] == 0.0) > 10  # a foot up in its swing is left free


def test_the_lock_sets_in_and_lets_go_with_zero_slope():
    """Around a contact the weight follows a smoothstep over the ramp, the same on both
    sides: a linear ramp's corners were the largest one-frame jerk of a restyled walk."""
    lock = FootLock(SK)
    roots, q = stepping(240)
    contacts = lock.push(roots, q)
    right = contacts[:, 1]
    start = int(np.flatnonzero(right[1:] & ~right[:-1])[0]) + 1  # the right foot's first touch-down
    w = lock.weights(0, 240)[:, 1]
    r = lock.ramp
    u = np.arange(1, r + 1) / (r + 1)
    np.testing.assert_allclose(w[start - r:start], u * u * (3 - 2 * u))  # rises with zero slope at 0...
    assert w[start] == 1.0
    end = start + int(np.argmin(right[start:]))  # ...and falls after the contact the same way
    np.testing.assert_allclose(w[end:end + r], (u * u * (3 - 2 * u))[::-1])


def test_a_longer_release_lets_go_over_its_own_frames_and_sets_in_as_before():
    """``release`` (the stance's 8 frames): after a contact the weight falls by a smoothstep
    over those frames, looking only back; before one it rises over the ramp as before."""
    short, long = FootLock(SK), FootLock(SK, settings=ContactSettings(release=8))
    roots, q = stepping(240)
    right = short.push(roots, q)[:, 1]
    long.push(roots, q)
    start = int(np.flatnonzero(right[1:] & ~right[:-1])[0]) + 1
    end = start + int(np.argmin(right[start:]))
    w, w_short = long.weights(0, 240)[:, 1], short.weights(0, 240)[:, 1]
    u = np.arange(1, 9) / 9
    np.testing.assert_allclose(w[end:end + 8], (u * u * (3 - 2 * u))[::-1])
    assert w[end + 8] == 0.0 < w_short[end + 3] < w[end + 3]
    np.testing.assert_array_equal(w[start - 6:start + 1], w_short[start - 6:start + 1])  # no further ahead


def test_a_swing_shorter_than_the_lock_blends_has_no_corner():
    """A foot lifted for fewer frames than the release and ramp together: letting go of one
    contact and setting into the next overlap, and the weight must stay smooth there. The
    larger of the two (the known-bad join) has a corner where they cross: a foot set down 7
    frames into a clip, its lock over the mirrored lead-in let go over 8 frames, popped the
    toes at 2.9x the input's largest one-frame jerk (a held-out walk made active)."""
    contacts = np.zeros(40)
    contacts[:10] = contacts[18:] = 1.0  # lifted for 8 frames; release 8 + ramp 4 overlap
    kernel = lock_kernel(4, 8, 8)
    windows = np.lib.stride_tricks.sliding_window_view(np.concatenate([np.ones(8), contacts, np.ones(4)]), 13)
    joined = lock_weights(windows, kernel, 8)
    larger = (windows * kernel).max(axis=-1)
    assert joined.min() > 0.0 and np.all(joined[:10] == 1.0) and np.all(joined[18:] == 1.0)
    slope_change = lambda w: np.abs(np.diff(w, 2)).max()
    assert slope_change(joined) < 0.2 < slope_change(larger)


def test_performers_pushed_in_one_call_detect_the_contacts_each_detects_alone():
    """The daemon pushes every performer's input frames of a tick in one call (``push_frames``:
    one vectorised leg FK for all, each with its own proportions); each lock must find the
    contacts and floors it finds alone, two frames of one performer in one call included."""
    roots, q = stepping(200)
    glide = roots.copy()
    glide[100:, 2] = 5.0 * np.arange(100)
    performers = [(SK, roots), (SK.with_offsets(SK.offsets * 0.85), roots * [1, 0.85, 1]), (SK, glide)]
    together = [FootLock.for_stream(sk, 5) for sk, _ in performers]
    alone = [FootLock.for_stream(sk, 5) for sk, _ in performers]
    for t in range(0, len(q), 2):
        push_frames([(lock, r[k], q[k]) for lock, (_, r) in zip(together, performers) for k in (t, t + 1)])
        for lock, (_, r) in zip(alone, performers):
            lock.push(r[t:t + 1], q[t:t + 1])
            lock.push(r[t + 1:t + 2], q[t + 1:t + 2])
    for a, b in zip(together, alone):
        assert a.frames == b.frames == len(q)
        np.testing.assert_array_equal(a._contacts, b._contacts)
        np.testing.assert_allclose(a._floors, b._floors, atol=1e-9)
    assert 0 < together[0].planted_frames < 2 * len(q)  # the steps plant and lift
    assert together[2].planted_frames < together[0].planted_frames  # gliding off the floor step releases


def test_a_foot_lifted_slowly_through_the_hysteresis_band_is_found_alike_one_frame_at_a_time_and_whole():
    """A foot raised slowly (under the plant speed) from the floor to 12 cm, held, and let
    down again: it stays planted until it is higher than the release height and plants again
    only below the plant height. Frame by frame (``push`` of one frame), a tick of several
    performers (``push_frames``) and the whole clip must find the same contacts."""
    frames = 360
    roots, q = stepping(frames)
    lift = np.interp(np.arange(frames), [0, 60, 150, 210, 300, frames], [0, 0, 1, 1, 0, 0])
    for bone, angle, soft in (("RightUpperLeg", -0.9, -0.2), ("RightLowerLeg", 1.4, 0.4)):
        j = HUMANOID_BONES.index(bone)
        q[:, j] = rot.multiply(rot.exp_map(np.outer(angle * lift, [1.0, 0.0, 0.0])),
                               rot.exp_map(np.array([soft, 0.0, 0.0])))
    pos, _, _ = leg_chain(roots, q, SK.offsets)
    height = pos[:, 1, 3, 1] - pos[:, :, 3, 1].min()  # the right ball above the lowest ball
    speed = np.linalg.norm(np.diff(pos[:, 1, 3], axis=0), axis=-1)
    settings = ContactSettings()
    assert height.max() > settings.release_height + 3 and speed.max() < settings.plant_speed
    assert np.sum((height > settings.plant_height) & (height < settings.release_height)) > 20  # the band, slowly

    whole_lock = FootLock(SK)
    whole = whole_lock.push(roots, q)  # as detected
    single = FootLock(SK)
    one_at_a_time = np.concatenate([single.push(roots[t:t + 1], q[t:t + 1]) for t in range(frames)])
    small, small_roots = SK.with_offsets(SK.offsets * 0.85), roots * [1, 0.85, 1]  # a second performer
    ticked = [FootLock(SK), FootLock(small)]
    for t in range(frames):
        push_frames([(ticked[0], roots[t], q[t]), (ticked[1], small_roots[t], q[t])])
    small_whole = FootLock(small)
    small_whole.push(small_roots, q)
    np.testing.assert_array_equal(one_at_a_time, whole)
    # As the locks use them: the first frame took the second's (it has no speed of its own).
    assert not whole[0].any() and whole_lock._contacts[0].tolist() == whole[1].tolist() == [True, True]
    np.testing.assert_array_equal(whole_lock._contacts[1:], whole[1:])
    for lock in (single, ticked[0]):
        np.testing.assert_array_equal(lock._contacts, whole_lock._contacts)
    np.testing.assert_array_equal(ticked[1]._contacts, small_whole._contacts)
    right = whole[:, 1].copy()
    right[0] = True  # (a stream's first frame has no speed, so no contact: not a landing)
    lifted, landed = np.flatnonzero(right[:-1] & ~right[1:]) + 1, np.flatnonzero(~right[:-1] & right[1:]) + 1
    assert len(lifted) == len(landed) == 1 and lifted[0] < landed[0]
    assert height[lifted[0]] > settings.release_height and height[lifted[0] - 1] > settings.plant_height
    assert height[landed[0]] < settings.plant_height and height[landed[0] - 1] < settings.release_height
    assert whole[1:, 0].all()  # the standing foot never lets go


@pytest.mark.parametrize("ramps, releases, sights", [((4, 4, 4), (None, None, None), (4, 4, 4)),
                                                     ((4, 4, 4), (8, None, 2), (4, 4, 4)),
                                                     ((4, 2, 0), (None, None, None), (4, 2, 0)),
                                                     ((4, 4, 4), (8, None, None), (1, 4, 2))])
def test_locks_planned_in_one_call_plan_what_each_plans_alone(ramps, releases, sights):
    """The daemon plans every performer's frame of a tick in one call (``plan_locks``: the
    lock weights of all in one pass); each job must be the one ``FootLock.plan`` makes,
    weights through touch-downs and lift-offs, floor and the input's feet, past the
    trimming of the histories (locks of different ramps plan one by one; different
    releases, as ``--feet input`` and ``stance`` have, and different sights, in the same
    pass)."""
    roots, q = stepping(400)
    out = restyled(q)
    sizes = (1.0, 0.85, 1.1)
    settings = [ContactSettings(release=r) for r in releases]
    together, alone = ([FootLock(SK.with_offsets(SK.offsets * k), ramp=r, settings=c, sight=v)
                        for k, r, c, v in zip(sizes, ramps, settings, sights)] for _ in range(2))
    scaled = [roots * [1, k, 1] for k in sizes]
    for t in range(len(q)):
        for a, b, r in zip(together, alone, scaled):
            a.push(r[t:t + 1], q[t:t + 1])
            b.push(r[t:t + 1], q[t:t + 1])
        k = t - max(ramps)
        if k < 0:
            continue
        jobs = plan_locks([(lock, k, r[k], q[k], out[k], None) for lock, r in zip(together, scaled)])
        for job, lock, r in zip(jobs, alone, scaled):
            expected = lock.plan(k, r[k:k + 1], q[k:k + 1], out[k:k + 1])
            for name in ("roots", "inputs", "outputs", "weights", "down", "floor", "own"):
                np.testing.assert_array_equal(getattr(job, name), getattr(expected, name), err_msg=name)
    assert all(0 < lock.planted_frames < 2 * len(q) for lock in together)
    assert len({lock._base for lock in together}) == 1 and together[0]._base > 0  # the histories were trimmed alike
