"""The foot lock (motion/footlock/): contacts with hysteresis, a planted foot kept where
the input put it to within a millimetre, bone lengths kept, the same result streamed a
frame at a time as for a whole clip, and nothing done where no foot is planted."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stylecast.motion import rotations as rot
from stylecast.motion.footlock import (AUTO_FEET, FEET, LEG_INDEX, LEGS, ContactSettings, FootLock, PelvisHeight,
                                      StanceOffset, feet_for, kept_clearance, leg_chain, lock_kernel, plan_locks,
                                      push_frames, solve_legs, solve_lock_jobs)
from stylecast.motion.footlock.contacts import hysteresis, lock_weights
from stylecast.motion.footlock.solve import CLEARANCE_BAND, CLEARANCE_SLACK
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default
from stylecast.motion.smoothing import CorrectionFilter
from stylecast.motion.words import BlendSettings

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
    state = hysteresis(plant, release, np.array([False]))[:, 0]
    assert state.tolist() == [False, True, True, True, False, False]


ON_INPUT_ANKLES, STANCE = FEET["input"], FEET["stance"]  # --feet input (the default), --feet stance


def horizontal_speed(p: np.ndarray) -> np.ndarray:
    """(n, 2, 3) positions -> (n - 1, 2) cm per frame on the floor plane."""
    return np.linalg.norm(np.diff(p[..., [0, 2]], axis=0), axis=-1)


def test_a_planted_foot_stays_still_and_legs_keep_their_length():
    roots, q = stepping()
    out_in = restyled(q)
    p_in, _, _ = leg_chain(roots, q, SK.offsets)
    p_raw, _, _ = leg_chain(roots, out_in, SK.offsets)
    for settings in (STANCE, ON_INPUT_ANKLES):
        lock = FootLock(SK, settings=settings)
        contacts = lock.push(roots, q)
        locked_roots, locked = lock.apply(0, roots, q, out_in)
        p_out, _, _ = leg_chain(locked_roots, locked, SK.offsets)
        still = contacts[1:] & contacts[:-1]
        raw_slide = horizontal_speed(p_raw[:, :, 2])[still]
        slide = horizontal_speed(p_out[:, :, 2])[still] - horizontal_speed(p_in[:, :, 2])[still]
        assert raw_slide.max() > 0.5  # without the lock the planted foot wanders
        assert slide.max() < settings.stance_rate + 1e-3  # with it: still (within the stance's creep)
        for side, (upper, lower, foot, toes) in enumerate(LEGS):
            for k, bone in ((1, lower), (2, foot)):
                length = np.linalg.norm(p_out[:, side, k] - p_out[:, side, k - 1], axis=-1)
                np.testing.assert_allclose(length, np.linalg.norm(SK.offsets[bone]), atol=1e-9)
    # Without the stance offset the planted foot is the input's own, within a millimetre
    # (positions in cm), the ball of the foot too (foot orientation and toes from the input).
    err = np.linalg.norm(p_out[:, :, 2:4] - p_in[:, :, 2:4], axis=-1)[contacts]
    assert err.max() < 0.1


def spread(q: np.ndarray, degrees: np.ndarray) -> np.ndarray:
    """A 'restyle' into a wider stance: each thigh rolled outwards by ``degrees`` (per frame)."""
    out = q.copy()
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        j = HUMANOID_BONES.index(f"{side}UpperLeg")
        v = np.zeros((len(q), 3))
        v[:, 2] = sign * np.radians(degrees)
        out[:, j] = rot.multiply(out[:, j], rot.exp_map(v))
    return out


def test_a_restyled_stance_is_kept_and_a_planted_foot_only_creeps_into_a_new_one():
    roots, q = stepping(240)
    standing = np.tile(q[:1], (240, 1, 1))  # both feet planted all the time
    roots = np.tile(roots[:1], (240, 1))
    angle = np.where(np.arange(240) < 120, 4.0, 0.0)  # wide for two seconds, then narrow again
    out_in = spread(standing, angle)
    p_in, _, _ = leg_chain(roots, standing, SK.offsets)
    p_raw, _, _ = leg_chain(roots, out_in, SK.offsets)

    def width(p):
        return np.abs(p[:, 0, 2, 0] - p[:, 1, 2, 0])

    # the restyle spreads the feet, each within the stance's cap
    assert 10.0 < (width(p_raw) - width(p_in))[:120].min() < 2 * STANCE.stance_cap
    results = {}
    for name, settings in (("stance", STANCE), ("input", ON_INPUT_ANKLES)):
        lock = FootLock(SK, settings=settings)
        contacts = lock.push(roots, standing)
        new_roots, out = lock.apply(0, roots, standing, out_in)
        results[name] = p_out = leg_chain(new_roots, out, SK.offsets)[0]
        assert contacts[1:].all()
        assert horizontal_speed(p_out[1:, :, 2]).max() < settings.stance_rate + 1e-6  # never slides
    kept, lost = width(results["stance"]), width(results["input"])
    np.testing.assert_allclose(kept[:120], width(p_raw)[:120], atol=0.05)  # the wide stance is kept
    np.testing.assert_allclose(lost[1:], width(p_in)[1:], atol=0.05)  # locked on the input's ankles: undone
    # When the restyle narrows the stance again the planted feet creep, 0.6 cm a second.
    assert kept[-1] < kept[119] - 2 * 120 * 0.01 + 0.05


def test_a_planted_foot_stands_no_further_than_the_stance_cap_beside_the_input():
    """An offset is taken as the lock blends in, while the restyled foot still swings, so a
    large one is mostly swing: capped at 8 cm the multistyle model's knees popped 2.0-3.1x
    the input's largest jerk in its worst clips, against 3.1-4.0x at 15 cm."""
    roots, q = stepping(120)
    standing = np.tile(q[:1], (120, 1, 1))
    roots = np.tile(roots[:1], (120, 1))
    out_in = spread(standing, np.full(120, 12.0))
    p_in, p_raw = leg_chain(roots, standing, SK.offsets)[0], leg_chain(roots, out_in, SK.offsets)[0]
    lock = FootLock(SK, settings=STANCE)
    lock.push(roots, standing)
    new_roots, out = lock.apply(0, roots, standing, out_in)
    offset = np.linalg.norm((leg_chain(new_roots, out, SK.offsets)[0] - p_in)[:, :, 2][..., [0, 2]], axis=-1)
    assert np.linalg.norm((p_raw - p_in)[:, :, 2][..., [0, 2]], axis=-1).min() > STANCE.stance_cap + 5.0
    assert np.abs(offset[1:] - STANCE.stance_cap).max() < 0.05  # as far as allowed, and no further


@pytest.mark.parametrize("paced, sight", [(False, 4), (True, 4), (False, 1), (True, 1)])
def test_streaming_a_frame_at_a_time_equals_the_whole_clip(paced, sight):
    """Applied ``sight`` frames behind the newest pushed (a stream's delay), as for the whole
    clip pushed at once: with a sight short of the ramp the lock foresees what the whole
    clip would show it, and reads nothing of it."""
    roots, q = stepping(180)
    out_in = restyled(q)
    settings = ContactSettings()
    mix = None
    if paced:  # gliding on at 0.3 cm a frame (slow enough to plant), slowed to 0.8 of it as the restyle fades in
        roots = roots + np.outer(0.3 * np.arange(len(q)), [0.0, 0.0, 1.0])
        settings = replace(settings, pace=((0.3, 0.24),))
        mix = np.clip((np.arange(len(q)) - 20) / 30.0, 0.0, 1.0)
    whole = FootLock(SK, ramp=4, settings=settings, sight=sight)
    whole.push(roots, q)
    expected_roots, expected = whole.apply(0, roots, q, out_in, mix)
    live = FootLock(SK, ramp=4, settings=settings, sight=sight)
    got, got_roots = [], []
    for t in range(len(q)):
        live.push(roots[t:t + 1], q[t:t + 1])
        k = t - sight
        if k >= 0:
            r, frame = live.apply(k, roots[k:k + 1], q[k:k + 1], out_in[k:k + 1], None if mix is None else mix[k:k + 1])
            got.append(frame[0])
            got_roots.append(r[0])
    assert rot.angle_between(np.array(got), expected[:len(got)]).max() < 1e-9
    np.testing.assert_allclose(np.array(got_roots), expected_roots[:len(got)], atol=1e-9)
    assert np.ptp(expected_roots[:, 1]) > 0.5  # the pelvis height really moved
    travelled, input_travel = expected_roots[-1, 2] - expected_roots[0, 2], roots[-1, 2] - roots[0, 2]
    assert travelled < 0.9 * input_travel if paced else travelled == input_travel == 0.0


OTHER_STANCE = replace(STANCE, stance_cap=3.0, stance_rate=0.03, turn_cap=10.0, turn_rate=0.1, turn_unsure=1.0,
                       turn_sure=4.0)


def test_performers_solved_in_one_call_equal_each_solved_alone():
    """The daemon solves every performer's frame of a tick in one vectorised call, each
    with its own proportions and lock; each must come out as it does alone (to rounding:
    one lock alone takes its feet on Python floats). Five
    performers: three body sizes, both locks (two stances of different settings), one
    gliding off (the floor step, not the lock) at a slower pace."""
    roots, q = stepping(200)
    glide = roots.copy()
    glide[100:, 2] = 5.0 * np.arange(100)
    performers = [(SK, ON_INPUT_ANKLES, roots, restyled(q)),
                  (SK.with_offsets(SK.offsets * 0.85), ON_INPUT_ANKLES, roots * [1, 0.85, 1], restyled(q, 20.0)),
                  (SK.with_offsets(SK.offsets * 1.1), STANCE, roots * [1, 1.1, 1], restyled(q)),
                  (SK, replace(ON_INPUT_ANKLES, pace=((2.0, 1.5),)), glide, crouched(q)),  # and a pace
                  (SK, OTHER_STANCE, roots, restyled(q, 20.0))]  # a stance of other settings beside the first
    together = [FootLock.for_stream(sk, 5, feet, fade_in=30) for sk, feet, _, _ in performers]
    alone = [FootLock.for_stream(sk, 5, feet, fade_in=30) for sk, feet, _, _ in performers]
    lifted = locked = 0
    for t in range(len(q)):
        for lock_a, lock_b, (_, _, r, _) in zip(together, alone, performers):
            lock_a.push(r[t:t + 1], q[t:t + 1])
            lock_b.push(r[t:t + 1], q[t:t + 1])
        k = t - 4
        if k < 0:
            continue
        mix = np.array([min(1.0, k / 60.0)])  # the restyle fading in (what the pace is scaled by)
        jobs = [lock.plan(k, r[k:k + 1], q[k:k + 1], out[k:k + 1], mix) for lock, (_, _, r, out) in
                zip(together, performers)]
        solve_lock_jobs(jobs)
        for job, lock, (_, _, r, out) in zip(jobs, alone, performers):
            new_roots, rotations = lock.apply(k, r[k:k + 1], q[k:k + 1], out[k:k + 1], mix)
            np.testing.assert_allclose(job.new_roots, new_roots, rtol=0, atol=1e-9)
            np.testing.assert_allclose(job.result, rotations, rtol=0, atol=1e-12)
        locked += sum(job.weights.any() for job in jobs)
        lifted += not np.array_equal(jobs[3].result, jobs[3].outputs) and not jobs[3].weights.any()
    assert locked > 300 and lifted > 10  # both the lock and the floor step were exercised
    assert np.ptp([lock.pace._shift[1] for lock in together]) > 10.0  # the pace held one body back
    assert [lock.locked_frames for lock in together] == [lock.locked_frames for lock in alone]


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
    limit = np.minimum(floor[:, None] + lock.ankle_rest, p_in[:, :, 2, 1])
    assert (limit - p_raw[:, :, 2, 1]).max() > 3.0  # without the floor: centimetres under
    assert (limit - p_out[:, :, 2, 1]).max() < 1e-6  # with it: nowhere below
    lengths = np.linalg.norm(p_out[:, :, 2] - p_out[:, :, 1], axis=-1)
    np.testing.assert_allclose(lengths, np.linalg.norm(SK.offsets[LEGS[0][2]]), atol=1e-9)


def gliding(frames: int, still: int):
    """A standing pose that stands ``still`` frames (both feet planted), then glides 5 cm a
    frame (nothing planted), and its restyle pitching both feet toes-down into the floor."""
    roots, q = stepping(frames)
    q = np.tile(q[:1], (frames, 1, 1))
    roots = np.tile(roots[:1], (frames, 1))
    roots[:, 2] = 5.0 * np.maximum(np.arange(frames) - still, 0)
    toes_down = q.copy()
    for side in ("Left", "Right"):
        j = HUMANOID_BONES.index(f"{side}Foot")
        toes_down[:, j] = rot.multiply(q[:, j], rot.exp_map(np.array([0.5, 0.0, 0.0])))
    return roots, q, toes_down


def test_a_foot_pitched_into_the_floor_is_lifted_onto_it():
    roots, q, toes_down = gliding(120, still=10)
    lock = FootLock(SK)
    contacts = lock.push(roots, q)
    assert contacts[1:10].all() and not contacts[12:].any()  # planted while still, then gliding
    new_roots, out = lock.apply(0, roots, q, toes_down)
    glide = slice(20, None)  # the locks have let go
    p_in, w_in, _ = (x[glide] for x in leg_chain(roots, q, SK.offsets))
    p_raw, w_raw, _ = (x[glide] for x in leg_chain(new_roots, toes_down, SK.offsets))
    p_out, w_out, _ = (x[glide] for x in leg_chain(new_roots, out, SK.offsets))
    floor = p_in[:, :, 3, 1].min()
    assert (floor - p_raw[:, :, 3, 1]).min() > 2.0  # the balls go centimetres under
    np.testing.assert_allclose(p_out[:, :, 3, 1], floor, atol=1e-6)  # lifted onto the floor...
    assert rot.angle_between(w_out[:, :, 2], w_raw[:, :, 2]).max() < 1e-6  # ...the foot turned as restyled
    np.testing.assert_allclose(p_out[:, :, 2, [0, 2]], p_raw[:, :, 2, [0, 2]], atol=1e-6)  # straight up


def test_no_floor_is_kept_before_a_foot_has_stood_on_one():
    """The floor is the lowest ball seen; before any contact that may be a foot in the air
    (a stream started mid-step), so nothing is lifted onto it until a foot has planted.
    (Kept at once, a floor that fell 3.5 cm in a frame as lower steps came dropped a lifted
    ankle with it: a 12-degree knee pop in tests/test_daemon.py's fault test.)"""
    roots, q, toes_down = gliding(60, still=0)
    lock = FootLock(SK)
    assert not lock.push(roots, q).any()
    _, out = lock.apply(0, roots, q, toes_down)
    assert rot.angle_between(out, toes_down).max() < 1e-9  # the restyle as it came


def test_the_soft_floor_is_continuous_with_its_slope_and_never_lifts_above_the_input():
    from stylecast.motion.footlock.solve import FLOOR_MARGIN, _soft_floor

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


def test_the_low_latency_preset_keeps_planted_feet_planted_on_a_real_walk(bandai_root):
    """A held-out walk through the shipped pair model at hop 1 with one frame of delay, as
    ``serve --latency low`` sends it: the foot lock's foresight keeps the planted feet's
    slide and the feet's jerk near the input's; the known-bad lock that sets in over the one
    frame it sees slid the planted feet 1.7x the input's (held-out walks and runs: 1.6-2.1x,
    1.05-1.17x foreseeing)."""
    from stylecast.models import metrics as M
    from stylecast.models.restyle import restyle_rotations
    from stylecast.models.restyler import Restyler
    from stylecast.motion.bvh import read_bvh
    from stylecast.motion.humanoid import Retarget
    from stylecast.motion.resample import resample
    from stylecast.motion.words import stream_settings_of

    clip = read_bvh(bandai_root / "dataset-2" / "data" / "dataset-2_walk_normal_010.bvh.gz")
    humanoid = resample(Retarget.for_clip(clip).to_humanoid(clip), 60.0)
    inp, roots = humanoid.rotations.astype(np.float64), humanoid.root_positions.astype(np.float64)
    r = Restyler.load(None).with_performer_style("normal")
    r = r.for_target(r.default_target)
    own = feet_for(AUTO_FEET, r)
    p_in = M.world_positions(inp, roots, humanoid.skeleton)
    planted = M.planted(p_in)
    feet = [HUMANOID_BONES.index(f"{side}{bone}") for side in ("Left", "Right") for bone in ("Foot", "Toes")]

    def slide_and_jerk(contacts):
        out, moved = restyle_rotations(inp, r.restyle_words, 1, contacts=contacts, roots=roots, live=True,
                                       skeleton=humanoid.skeleton, **stream_settings_of(r))
        p = M.world_positions(out, moved, humanoid.skeleton)
        slide = M.slide_samples(p, planted).mean() / M.slide_samples(p_in, planted).mean()
        return slide, M.jerk(p)[:, feet].mean() / M.jerk(p_in)[:, feet].mean()

    slide, jerk = slide_and_jerk(own)
    slide_snapping, jerk_snapping = slide_and_jerk(replace(own, ramp=1))
    assert slide < 1.25 and slide_snapping > 1.5
    assert jerk < jerk_snapping - 0.2


def solved_knees(thigh_degrees: np.ndarray, knee_degrees, lift: float,
                 sideways: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The left leg swung forward by each of ``thigh_degrees`` about the hip (its knee bent
    ``knee_degrees``, one value or one per frame, below 0 past straight, and ``sideways``
    degrees out of its hinge), solved onto one fixed target: the ankle of the unswung,
    straight leg raised ``lift`` cm, so the knee must fold -> (solved knee positions (n, 3),
    the socket, how far each ankle is from its target)."""
    n = len(thigh_degrees)
    bend = np.radians(np.broadcast_to(np.asarray(knee_degrees, float), (n,)))
    q = np.tile(rot.identity((J,)), (n, 1, 1))
    upper, lower = (HUMANOID_BONES.index(f"Left{b}") for b in ("UpperLeg", "LowerLeg"))
    q[:, upper] = rot.exp_map(np.stack([-np.radians(thigh_degrees), 0 * thigh_degrees, 0 * thigh_degrees], -1))
    q[:, lower] = rot.exp_map(np.stack([bend, 0 * bend, np.radians(sideways) + 0 * bend], -1))
    roots = np.tile([0.0, 100.0, 0.0], (n, 1))
    straight, world, _ = leg_chain(roots[:1], np.tile(rot.identity((J,)), (1, 1, 1)), SK.offsets)
    target = np.repeat(straight[:, :, 2] + [0.0, lift, 0.0], n, axis=0)
    out = q.copy()
    out[:, LEG_INDEX[:, :3]] = solve_legs(roots, q, SK.offsets, target, np.repeat(world[:, :, 2], n, axis=0))
    pos = leg_chain(roots, out, SK.offsets)[0]
    return pos[:, 0, 1], pos[0, 0, 0], np.linalg.norm(pos[:, 0, 2] - target[:, 0], axis=-1)


def test_a_knee_asked_to_fold_keeps_its_side_as_the_leg_swings_past_its_target():
    """A planted foot held behind a leg that swung on: the restyled knee crossed the line
    from hip to target and the fold flipped from front to back in one frame (36 cm, a
    held-out walk). The knee folds the way it points off its own hip-ankle line; a straight
    leg folds forward of its thigh (+z)."""
    sweep = np.linspace(-5.0, 5.0, 201)  # the thigh from 5 degrees back to 5 forward, 0.05 apart
    for knee_degrees in (6.0, 0.0):  # a slightly bent knee, and a straight leg
        knees, socket, miss = solved_knees(sweep, knee_degrees, lift=6.0)
        assert miss.max() < 1e-6  # the ankle is on its target
        assert (knees[:, 2] - socket[2] > 5.0).all()  # always in front
        assert np.linalg.norm(np.diff(knees, axis=0), axis=-1).max() < 0.5  # never a jump


def test_a_knee_asked_to_fold_as_its_leg_straightens_past_straight_keeps_its_side():
    """A leg that straightens at heel strike, a hair past straight and a little out of its
    hinge (a restyle may do both), while the floor or the lock folds it by 2 mm: the knee's
    own direction off its hip-ankle line then turns from forward through sideways to
    backward, and a fold that followed it turned a knee 4 cm sideways and back in one frame
    (a held-out walk made youthful, a pop 9.5x the input's largest jerk). A knee is a hinge
    that folds forward of its thigh."""
    knee_degrees = np.linspace(3.0, -1.0, 201)  # bent, straight, then a degree past it
    knees, socket, miss = solved_knees(np.zeros(201), knee_degrees, lift=0.2, sideways=0.5)
    assert (knees[:, 2] - socket[2] > 1.0).all()  # always in front
    assert np.linalg.norm(np.diff(knees, axis=0), axis=-1).max() < 0.1  # never a jump
    assert miss.max() < 0.4  # within 2 mm of full stretch: the soft reach (the next test)


def test_a_knee_moves_smoothly_as_its_target_crosses_full_stretch():
    """Soft reach: a planted leg held straight whose target comes within reach at 0.1 mm a
    frame (the pelvis settling). With a plain clamp at full stretch the knee jumped in the
    first frames inside reach (its height grows as the square root of how far inside): a
    standing figure's knee twitched, 4.5x the input's largest jerk. The ankle falls short of
    its target by at most SOFT_REACH / e at full stretch and not at all from SOFT_REACH
    inside it."""
    from stylecast.motion.footlock.legs import SOFT_REACH

    n = 400
    q = np.tile(rot.identity((J,)), (n, 1, 1))
    q[:, HUMANOID_BONES.index("LeftLowerLeg")] = rot.exp_map(np.array([np.radians(2.0), 0.0, 0.0]))
    roots = np.tile([0.0, 100.0, 0.0], (n, 1))
    straight, world, _ = leg_chain(roots[:1], np.tile(rot.identity((J,)), (1, 1, 1)), SK.offsets)
    inside = np.linspace(-1.0, 3.0, n)  # cm inside full stretch: beyond reach, then within it
    target = np.repeat(straight[:, :, 2], n, axis=0) + inside[:, None, None] * [0.0, 1.0, 0.0]
    out = q.copy()
    out[:, LEG_INDEX[:, :3]] = solve_legs(roots, q, SK.offsets, target, np.repeat(world[:, :, 2], n, axis=0))
    pos = leg_chain(roots, out, SK.offsets)[0]
    knee = pos[:, 0, 1]
    assert np.linalg.norm(np.diff(knee, axis=0), axis=-1).max() < 0.1  # never a jump
    assert np.linalg.norm(np.diff(knee, 3, axis=0), axis=-1).max() < 0.01  # nor a kink
    miss = np.linalg.norm(pos[:, 0, 2] - target[:, 0], axis=-1)
    assert miss[inside >= 0].max() <= SOFT_REACH / np.e + 1e-6
    assert miss[inside >= SOFT_REACH].max() < 1e-6


def test_a_foot_that_comes_down_onto_the_floor_is_eased_into_the_lift():
    """A foot held up in the air (not planted) that the restyle lowers onto the floor by
    straightening its knee, a little out of its hinge: the floor step bends the leg in by
    the lift it needs (FLOOR_LIFT_EASE). Switched in at once, the leg moved by the
    difference of the two solutions in the first frame of a lift of nothing (0.22 cm here;
    in held-out walks knee pops up to 6x the input's largest jerk)."""
    n = 240
    roots, q = stepping(1)
    q, roots = np.repeat(q, n, axis=0), np.repeat(roots, n, axis=0)
    upper, lower = (HUMANOID_BONES.index(f"Right{b}") for b in ("UpperLeg", "LowerLeg"))
    q[:, upper] = rot.exp_map(np.array([-0.1, 0.0, 0.0]))
    q[:, lower] = rot.exp_map(np.array([1.0, 0.0, 0.0]))  # the input's foot 19 cm up, still
    out = q.copy()
    # The restyle straightens the knee from the input's bend down through the clearance the
    # input keeps near the floor (``CLEARANCE_BAND``: the ankle 4.5 cm above standing height).
    bend = np.linspace(1.0, 0.38, n)
    out[:, lower] = rot.exp_map(np.stack([bend, 0 * bend, np.radians(3.0) + 0 * bend], -1))
    lock = FootLock(SK)
    assert not lock.push(roots, q)[:, 1].any()
    new_roots, result = lock.apply(0, roots, q, out)
    p_out, p_raw = leg_chain(new_roots, result, SK.offsets)[0], leg_chain(roots, out, SK.offsets)[0]
    lifted = p_out[:, 1, 2, 1] - p_raw[:, 1, 2, 1] > 1e-6
    assert 0 < lifted.argmax() and lifted.sum() > n // 2  # the lift begins part way through
    assert np.linalg.norm(np.diff(p_out[:, 1, 1], axis=0), axis=-1).max() < 0.1  # the knee never jumps


def test_the_kept_clearance_follows_the_input_near_the_floor_and_saturates_smoothly():
    base = np.zeros(6)
    own = np.array([0.0, 0.5, 1.0, CLEARANCE_BAND, 3 * CLEARANCE_BAND, 100.0])
    kept = kept_clearance(own, base) + CLEARANCE_SLACK
    assert kept[0] == 0.0 and np.all(np.diff(kept) > 0) and kept[-1] < CLEARANCE_BAND + 1e-9
    np.testing.assert_allclose(kept[1:3], own[1:3], rtol=0.02)  # near the floor: the input's own
    # No corner where the band is reached: the slope falls off smoothly (a cap's corner popped a knee).
    h = np.linspace(0.0, 3 * CLEARANCE_BAND, 3001)
    slope = np.diff(kept_clearance(h, np.zeros_like(h)))
    assert np.abs(np.diff(slope)).max() < 2e-5


def test_a_foot_in_the_air_near_the_floor_keeps_the_inputs_clearance_and_higher_up_the_restyles():
    """A landing heel the restyle (here a straighter knee) puts on the floor before the
    input's does: with the floor alone it was set down early and dragged there (a
    held-out walk: its ankle at standing height, moving 1.5-2 cm a frame). Near the
    floor it keeps the input's clearance (``kept_clearance``); well above CLEARANCE_BAND
    a swing is the restyle's own."""
    n = 60
    roots, q = stepping(1)
    q, roots = np.repeat(q, n, axis=0), np.repeat(roots, n, axis=0)
    upper, lower = (HUMANOID_BONES.index(f"Right{b}") for b in ("UpperLeg", "LowerLeg"))
    heights = {}
    # (hip, knee) of the input's right leg, then of the restyle's: held still in the air
    for name, leg_in, leg_out in (("near", (-0.1, 0.55), (-0.1, 0.3)), ("high", (-0.9, 1.0), (-0.7, 1.0))):
        out = q.copy()
        for x, (hip, knee) in ((q, leg_in), (out, leg_out)):
            x[:, upper] = rot.exp_map(np.array([hip, 0.0, 0.0]))
            x[:, lower] = rot.exp_map(np.array([knee, 0.0, 0.0]))
        lock = FootLock(SK, settings=ContactSettings(plant_height=0.5))  # its ball 0.7 cm up: in the air
        assert not lock.push(roots, q)[:, 1].any()  # the right foot is in the air throughout
        new_roots, result = lock.apply(0, roots, q, out)
        chains = [leg_chain(r, x, SK.offsets)[0][10:] for r, x in ((roots, q), (roots, out), (new_roots, result))]
        standing = chains[0][:, 0, 3, 1].min() + lock.ankle_rest  # the ankle's height standing on the floor
        heights[name] = [c[:, 1, 2, 1] - standing for c in chains]  # the input's, the restyle's, the lock's
    own, restyled, locked = heights["near"]
    # 4.5 cm up, within the band; the restyle takes 3 of them, towards the floor
    assert 1.0 < own.min() < CLEARANCE_BAND and restyled.max() < own.min() - 3.0
    assert np.all(locked > kept_clearance(own, 0.0) - 0.05) and np.all(locked <= own + 1e-6)
    assert locked.min() > restyled.max() + 1.5  # most of the input's clearance back
    own, restyled, locked = heights["high"]
    assert restyled.min() > 2 * CLEARANCE_BAND and own.min() > restyled.max() + 3.0
    np.testing.assert_allclose(locked, restyled, atol=1e-6)  # lowered by 3 cm or more, and left there


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


def test_a_stance_let_go_over_8_frames_does_not_snap_a_lifting_foot_to_its_swing(bandai_root):
    """The multistyle model made active, a held-out turning walk through the stream with
    its stance lock: by lift-off the restyled swing foot is up to ~17 cm from where the
    stance held it, and let go over 4 frames (the known-bad case) the foot jumped that gap:
    the feet's largest one-frame jerk 2.1x the input's; over the stance's 8 frames 1.4x."""
    from stylecast.models import metrics as M
    from stylecast.models.restyle import restyle_rotations
    from stylecast.models.restyler import Restyler
    from stylecast.motion.bvh import read_bvh
    from stylecast.motion.humanoid import Retarget
    from stylecast.motion.resample import resample
    from stylecast.motion.words import stream_settings_of

    clip = read_bvh(bandai_root / "dataset-2" / "data" / "dataset-2_walk-turn-right_normal_010.bvh.gz")
    humanoid = resample(Retarget.for_clip(clip).to_humanoid(clip), 60.0)
    inp, roots = humanoid.rotations.astype(np.float64), humanoid.root_positions.astype(np.float64)
    r = Restyler.load("multistyle").with_performer_style("normal").for_target("active")
    own = feet_for(AUTO_FEET, r)  # the model's stance lock at the style's pace
    assert own.stance_cap == STANCE.stance_cap and own.release == 8
    feet = [HUMANOID_BONES.index(f"{side}{bone}") for side in ("Left", "Right") for bone in ("Foot", "Toes")]
    jerk_in = M.jerk(M.world_positions(inp, roots, humanoid.skeleton))[:, feet]

    def feet_pops(release):
        out, moved = restyle_rotations(inp, r.restyle_words, contacts=replace(own, release=release), roots=roots,
                                       skeleton=humanoid.skeleton, **stream_settings_of(r))
        return M.jerk(M.world_positions(out, moved, humanoid.skeleton))[:, feet].max() / jerk_in.max()

    assert feet_pops(8) < 1.6
    assert feet_pops(4) > 1.9


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


def test_a_rig_that_is_not_the_humanoid_is_refused():
    from stylecast.motion.skeleton import Skeleton

    with pytest.raises(ValueError):
        FootLock(Skeleton(("a", "b"), (-1, 0), np.zeros((2, 3))))


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


def test_the_one_frame_float_path_equals_the_array_path():
    from stylecast.motion.footlock.legs import feet_of_one_frame

    roots, q = stepping(30)
    q = restyled(q)
    lock = FootLock(SK)
    pos, _, _ = leg_chain(roots, q, SK.offsets)
    for t in range(30):
        ankle, ball = feet_of_one_frame(roots[t], q[t], lock._leg_offsets)
        np.testing.assert_allclose(ankle, pos[t, :, 2], atol=1e-9)
        np.testing.assert_allclose(ball, pos[t, :, 3], atol=1e-9)


def test_a_restyled_turn_of_the_feet_is_kept_while_they_stay_planted():
    roots, q = stepping(120)
    standing = np.tile(q[:1], (120, 1, 1))
    roots = np.tile(roots[:1], (120, 1))
    toes_out = standing.copy()
    for side, sign in (("Left", 1.0), ("Right", -1.0)):  # each foot turned outwards by 20 degrees
        j = HUMANOID_BONES.index(f"{side}Foot")
        toes_out[:, j] = rot.multiply(toes_out[:, j], rot.exp_map(np.array([0.0, sign * np.radians(20.0), 0.0])))

    def heading(p):  # degrees about the vertical of each foot, ankle to ball
        d = p[:, :, 3] - p[:, :, 2]
        return np.degrees(np.arctan2(d[..., 0], d[..., 2]))

    p_in, p_raw = (leg_chain(roots, r, SK.offsets)[0] for r in (standing, toes_out))
    assert np.abs(heading(p_raw) - heading(p_in)).min() > 19.0
    for settings, expected in ((STANCE, p_raw), (ON_INPUT_ANKLES, p_in)):
        lock = FootLock(SK, settings=settings)
        lock.push(roots, standing)
        new_roots, out = lock.apply(0, roots, standing, toes_out)
        p_out = leg_chain(new_roots, out, SK.offsets)[0]
        np.testing.assert_allclose(heading(p_out)[1:], heading(expected)[1:], atol=0.1)
        assert horizontal_speed(p_out[1:, :, 3]).max() < 1e-6  # the balls of the feet do not move


def test_the_stance_turn_holds_while_a_foot_points_down():
    """A foot pointing straight down has no heading: the stance turn holds where it was
    rather than follow round-off (a landing foot was turned 54 degrees in one frame), and
    follows again in part as the foot comes back onto the floor."""
    stance = StanceOffset(STANCE)
    ankle = np.zeros((30, 2, 3))
    turned = np.radians(20.0) * np.ones(30)
    ball = np.stack([12 * np.sin(turned), 0 * turned, 12 * np.cos(turned)], -1)[:, None].repeat(2, axis=1)
    own = (ankle, ankle + [0.0, 0.0, 12.0])
    flat = stance.track(0, own, (ankle, ball), np.zeros((30, 2), bool))  # free: follows at once
    np.testing.assert_allclose(np.degrees(flat[:, :, 2]), 20.0)
    down = ball.copy()
    down[:, :, [0, 2]] = [[-0.3, 0.2], [0.4, -0.1]]  # nearly straight down: headings of round-off
    down[:, :, 1] = -12.0
    held = stance.track(30, own, (ankle, down), np.zeros((30, 2), bool))
    np.testing.assert_allclose(np.degrees(held[:, :, 2]), 20.0)
    part = np.zeros((1, 2, 3))
    part[:, :, 1:] = [-11.3, 4.0]  # 4 cm on the floor, half way from unsure to sure, heading 0
    step = stance.track(60, (ankle[:1], own[1][:1]), (ankle[:1], part), np.zeros((1, 2), bool))
    np.testing.assert_allclose(np.degrees(step[0, :, 2]), 10.0)  # half of the way to 0 in one frame


@pytest.mark.parametrize("settings", [STANCE, ON_INPUT_ANKLES], ids=["stance", "input"])
def test_a_planted_leg_bends_its_knee_the_way_the_restyle_turned_it(settings):
    """With either lock: knees the restyle turned in stay turned in (the input's knee plane
    undid them with ``--feet input``, and read less exhausted)."""
    roots, q = stepping(120)
    standing = np.tile(q[:1], (120, 1, 1))
    roots = np.tile(roots[:1], (120, 1))
    knees_in = crouched(standing)
    for side, sign in (("Left", -1.0), ("Right", 1.0)):  # each thigh twisted inwards about its length
        j = HUMANOID_BONES.index(f"{side}UpperLeg")
        knees_in[:, j] = rot.multiply(knees_in[:, j], rot.exp_map(np.array([0.0, sign * np.radians(25.0), 0.0])))

    def knee_direction(p):  # unit vector from the hip-ankle line to the knee
        axis = p[:, :, 2] - p[:, :, 0]
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        k = p[:, :, 1] - p[:, :, 0]
        k -= np.sum(k * axis, axis=-1, keepdims=True) * axis
        return k / np.linalg.norm(k, axis=-1, keepdims=True)

    lock = FootLock(SK, settings=settings)
    lock.push(roots, standing)
    new_roots, out = lock.apply(0, roots, standing, knees_in)
    got, wanted, plain = (knee_direction(leg_chain(r, x, SK.offsets)[0])
                          for r, x in ((new_roots, out), (roots, knees_in), (roots, crouched(standing))))
    angle = np.degrees(np.arccos(np.clip(np.sum(got * wanted, -1), -1, 1)))[1:]
    turned = np.degrees(np.arccos(np.clip(np.sum(plain * wanted, -1), -1, 1)))[1:]
    assert turned.min() > 15.0  # the twist really turns the knees
    assert angle.max() < 3.0  # and the locked legs keep it (while it comes down, the plane moves with the hip)
    if settings is STANCE:  # once the pelvis has settled, closely (the ankle stands at the cap, 8 cm
        assert angle[60:].max() < 1.0  # beside the input's, short of the restyled one: 0.74 degrees); on
        # the input's ankles, about their own hip-ankle line, not the restyle's (1.75 degrees here)


@pytest.mark.parametrize("aim", [1.0, 0.5])
def test_a_stream_fading_in_stands_in_the_restyled_stance_from_its_first_frame(aim):
    """A stream starts in pass-through and fades the restyle in (towards the intensity
    ``aim``) while the feet are down, as ``words.restyle_stream`` shows it: slerped by the
    seam blender's mix, then the correction low-passed. The planted feet stand where the
    restyle at that intensity puts them from the first frame, and never slide; following the
    fading stance (the lead-in's free follow, the known-bad case) slides them."""
    roots, q = stepping(240)
    standing = np.tile(q[:1], (240, 1, 1))
    roots = np.tile(roots[:1], (240, 1))
    settings = BlendSettings(hop=4, start_restyled=False)
    mix = np.minimum(aim, np.arange(1, 241) / settings.crossfade_frames)
    full = spread(standing, np.full(240, 4.0))
    shown = rot.slerp(standing, full, np.broadcast_to(mix[:, None], standing.shape[:2]))
    out_in = CorrectionFilter(J, settings.correction_tau).apply(standing, shown)

    def width(p):
        return np.abs(p[:, 0, 2, 0] - p[:, 1, 2, 0])

    wanted = width(leg_chain(roots, spread(standing, np.full(240, 4.0 * aim)), SK.offsets)[0])
    own = width(leg_chain(roots, standing, SK.offsets)[0])
    assert wanted[0] - own[0] > 4.0 * aim  # a stance worth keeping
    fade = settings.first_fade_end
    slides, widths = {}, {}
    for name, fade_in, lead_in in (("at the aim", fade, 0), ("following the fade", 0, fade), ("input's", 0, 0)):
        lock = FootLock.for_stream(SK, delay=5, settings=STANCE, fade_in=fade_in,
                                   fade_tau=settings.correction_tau, lead_in=lead_in, aim=aim)
        lock.push(roots, standing)
        new_roots, out = lock.apply(0, roots, standing, out_in, mix)
        p = leg_chain(new_roots, out, SK.offsets)[0]
        slides[name], widths[name] = horizontal_speed(p[:, :, 2]).max(), width(p)
    np.testing.assert_allclose(widths["at the aim"], wanted, atol=0.1)  # the stance at the aim, from frame 0 on
    assert slides["at the aim"] < STANCE.stance_rate + 1e-6  # and never slides
    assert slides["following the fade"] > 0.05  # the known-bad cases: following the fade slides,
    assert widths["input's"][fade] - own[fade] < (wanted[fade] - own[fade]) / 4  # and holding the input's keeps it


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
