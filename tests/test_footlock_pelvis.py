"""The pelvis height (motion/footlock/pelvis.py): the hips lower so a restyled knee bend stands on
the planted feet, settle slowly through a run's flights, stay within their cap, stand on the
feet down, and stream frame by frame as for a whole clip."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from stylecast.motion import rotations as rot
from stylecast.motion.footlock import FEET, ContactSettings, FootLock, PelvisHeight, leg_chain
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


def walking_gaps(frames: int = 240, stride: int = 16):
    """A walk's contacts (a foot always down, each in turn for ``stride`` frames); the
    restyle asks for a gap of 4 cm on the left foot and 1 cm on the right, so the hips move
    at every change of foot. Returns (gaps (n, 2), planted (n, 2))."""
    left = (np.arange(frames) // stride) % 2 == 0
    planted = np.stack([left, ~left], -1)
    return np.where(planted, [4.0, 1.0], 0.0), planted


def test_a_style_that_asks_for_quick_hips_gets_them_and_one_that_does_not_keeps_the_slow_ones_to_the_bit():
    """The stance's hips follow over 8 frames; masculine asks for 2 (its share of the
    low-pass: ``PelvisHeight.set_quick_share``, set by the style mix). At share 1 the hips
    are the 2-frame low-pass's, at 0 the 8-frame one's bit for bit, in between in part."""
    s = FEET["stance"]
    gaps, planted = walking_gaps()

    def drops(share=None, tau=s.pelvis_tau):
        quick = {} if share is None else {"quick_tau": s.pelvis_quick_tau, "quick_share": share}
        return PelvisHeight(tau, s.pelvis_cap, s.pelvis_flight_tau, s.flight_memory, **quick).drops(gaps, planted)

    slow, quick = drops(), drops(tau=s.pelvis_quick_tau)
    assert np.abs(slow - quick).max() > 1.0  # the two really differ through the walk's changes of foot
    np.testing.assert_array_equal(drops(0.0), slow)
    np.testing.assert_allclose(drops(1.0), quick, atol=1e-9)
    np.testing.assert_allclose(drops(0.25), 0.75 * slow + 0.25 * quick, atol=1e-9)


def test_a_live_change_of_style_moves_the_hips_to_the_quick_share_smoothly_frame_by_frame_as_a_clip():
    """A live switch to a style with quick hips crossfades the share over the lock's own
    low-pass: the hips never move faster than the quick low-pass alone moves them, where
    switching the share at once steps them (the known-bad case), and a stream frame by frame
    gives the clip's offsets."""
    s = FEET["stance"]
    gaps, planted = walking_gaps()
    switch = 40  # mid-stride, where the slow hips lag the quick ones most

    def hips(share_of_frame, frame_by_frame=False):
        p = PelvisHeight(s.pelvis_tau, s.pelvis_cap, s.pelvis_flight_tau, s.flight_memory,
                         s.pelvis_quick_tau, share_of_frame(0))
        out = []
        for t in range(len(gaps)) if frame_by_frame else (0, switch):
            end = t + 1 if frame_by_frame else (switch if t == 0 else len(gaps))
            p.set_quick_share(share_of_frame(t))
            out.append(p.drops(gaps[t:end], planted[t:end]))
        return np.concatenate(out)

    def speed(drops):
        return np.abs(np.diff(drops)).max()

    switched = hips(lambda t: float(t >= switch))
    quick = PelvisHeight(s.pelvis_quick_tau, s.pelvis_cap, s.pelvis_flight_tau, s.flight_memory).drops(gaps, planted)
    assert speed(switched) <= speed(quick) + 1e-9
    # The known-bad case: the share steps where the crossfade eases (an instant switch).
    stepped = PelvisHeight(s.pelvis_tau, s.pelvis_cap, s.pelvis_flight_tau, s.flight_memory).drops(gaps, planted)
    stepped[switch:] = quick[switch:]
    assert speed(stepped) > 1.5 * speed(quick)
    # ...and the crossfade reaches the quick hips (a triple pole: 99 % of the way within
    # eight of its time constants)
    settled = switch + 8 * int(s.pelvis_tau)
    assert np.abs(switched[settled:] - quick[settled:]).max() < 0.05 * np.abs(quick).max()
    np.testing.assert_allclose(hips(lambda t: float(t >= switch), frame_by_frame=True), switched, atol=1e-12)
