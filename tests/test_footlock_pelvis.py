"""The pelvis height (motion/footlock/pelvis.py): the hips lower so a restyled knee bend stands on
the planted feet, settle slowly through a run's flights, stay within their cap, stand on the
feet down, and stream frame by frame as for a whole clip."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from stylecast.motion import rotations as rot
from stylecast.motion.footlock import ContactSettings, FootLock, PelvisHeight, leg_chain
from tests.footlock_motion import SK, ON_INPUT_ANKLES, crouched, horizontal_speed, stepping


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
    assert np.abs(p_out[:, :, 2, 1] - p_in[:, :, 2, 1])[contacts].max() < 0.1  # feet on the floor...
    assert horizontal_speed(p_out[1:, :, 2]).max() < 1e-6  # ...and still
    # The hips settle smoothly from the stream's start (no step in height or speed).
    assert np.abs(np.diff(new_roots[:, 1], 2)).max() < 0.1 * gap


def test_on_the_input_ankles_the_hips_follow_a_restyled_bend_within_a_fifth_of_a_second():
    """The restyle bends the standing legs from frame 60 on: the hips come down by 90 % of
    the gap within 12 frames (pelvis_tau 2: 9 frames), so the knees bend step by step as
    restyled (with pelvis_tau 8, 41 frames, the previous pair default read walks 54 % exhausted, with
    2 78 %)."""
    roots, q = stepping(180)
    standing = np.tile(q[:1], (180, 1, 1))
    roots = np.tile(roots[:1], (180, 1))
    out_in = standing.copy()
    out_in[60:] = crouched(standing[60:])
    p_in, p_raw = leg_chain(roots, standing, SK.offsets)[0], leg_chain(roots, out_in, SK.offsets)[0]
    gap = float(np.mean(p_raw[-1, :, 2, 1] - p_in[-1, :, 2, 1]))
    lock = FootLock(SK, settings=ON_INPUT_ANKLES)
    lock.push(roots, standing)
    new_roots, _ = lock.apply(0, roots, standing, out_in)
    drop = roots[:, 1] - new_roots[:, 1]
    assert np.abs(drop[:60]).max() < 1e-9 and drop[60 + 12] > 0.9 * gap


def running_contacts(frames: int = 240, contact: int = 12, flight: int = 8):
    """A run's contacts: each foot in turn planted for ``contact`` frames, ``flight`` frames
    with neither down between; the restyle asks for a gap of 3 cm on the left foot and 1 cm
    on the right. Returns (gaps (n, 2), planted (n, 2))."""
    phase = np.arange(frames) % (2 * (contact + flight))
    planted = np.stack([phase < contact, (phase >= contact + flight) & (phase < 2 * contact + flight)], -1)
    return np.where(planted, [3.0, 1.0], 0.0), planted


def pelvis_jerk(drops: np.ndarray) -> float:
    return float(np.abs(np.diff(drops, 3)).max())


def test_through_a_runs_flights_the_hips_settle_slowly_and_while_a_foot_is_down_they_follow_fast():
    """A run's contacts (a flight between each) take the slow low-pass, a walk's (a foot
    always down) the fast one: hips that followed each new contact's gap within 2 frames
    snapped a held-out run's knee to 2.52x the input's largest jerk (1.19x with 8)."""
    s = ContactSettings()
    gaps, planted = running_contacts()
    fast = PelvisHeight(s.pelvis_tau, s.pelvis_cap)
    slow = PelvisHeight(s.pelvis_flight_tau, s.pelvis_cap)
    lock = PelvisHeight(s.pelvis_tau, s.pelvis_cap, s.pelvis_flight_tau, s.flight_memory)
    running = lock.drops(gaps, planted)
    assert pelvis_jerk(running[60:]) < 1.5 * pelvis_jerk(slow.drops(gaps, planted)[60:])
    assert pelvis_jerk(running[60:]) < 0.25 * pelvis_jerk(fast.drops(gaps, planted)[60:])
    # A walk: the same gaps with a foot always down, after the run has been forgotten.
    walk_planted = np.stack([planted[:, 0], ~planted[:, 0]], -1)
    walking = lock.drops(np.where(walk_planted, [3.0, 1.0], 0.0), walk_planted)
    expected = fast.drops(np.where(walk_planted, [3.0, 1.0], 0.0), walk_planted)
    np.testing.assert_allclose(walking[120:], expected[120:], atol=1e-3)


def test_the_pelvis_offset_of_a_stream_frame_by_frame_equals_the_whole_clips_through_flights():
    s = ContactSettings()
    gaps, planted = running_contacts(200)
    planted[150:] = [True, False]  # the run ends standing
    whole = PelvisHeight(s.pelvis_tau, s.pelvis_cap, s.pelvis_flight_tau, s.flight_memory).drops(gaps, planted)
    stream = PelvisHeight(s.pelvis_tau, s.pelvis_cap, s.pelvis_flight_tau, s.flight_memory)
    blocks = [stream.drops(gaps[t:t + 1], planted[t:t + 1]) for t in range(100)]
    blocks += [stream.drops(gaps[t:t + 7], planted[t:t + 7]) for t in range(100, 200, 7)]
    np.testing.assert_allclose(np.concatenate(blocks), whole, atol=1e-12)


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


def test_the_pelvis_stands_on_the_feet_down_not_on_a_foot_the_release_still_holds():
    """The hips drop by the gap of the feet that are down: a contact within the ramp. A
    foot that a longer release still holds is lifting (counted, its gap dropped the hips and
    popped a knee: the pair default's worst held-out clip, 1.2 -> 2.6x the input's largest
    one-frame jerk), so the pelvis of a lock released over 8 frames is the 4-frame one's."""
    roots, q = stepping(240)
    out = crouched(q)
    heights = []
    for release in (None, 8):
        lock = FootLock(SK, settings=replace(ON_INPUT_ANKLES, release=release))
        lock.push(roots, q)
        new_roots, locked = lock.apply(0, roots[:-4], q[:-4], out[:-4])
        heights.append(new_roots[:, 1])
    np.testing.assert_array_equal(heights[0], heights[1])
    assert np.ptp(heights[0]) > 1.0  # the hips did move with the feet down
