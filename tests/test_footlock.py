"""The foot lock (motion/footlock/): a planted foot kept where the input put it to within a
millimetre, bone lengths kept, the restyled stance and turn of the feet kept, the same result
streamed a frame at a time as for a whole clip and for performers in one call, and nothing done
where no foot is planted. Contacts and timing, the pelvis, and the legs and floor have files of
their own (test_footlock_contacts.py, _pelvis.py, _legs.py); the motion they share is
footlock_motion.py."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stylecast.motion import rotations as rot
from stylecast.motion.footlock import (AUTO_FEET, FEET, LEGS, FootLock, StanceOffset, feet_for, leg_chain,
                                       solve_lock_jobs)
from stylecast.motion.footlock.contacts import lock_kernel
from stylecast.motion.humanoid import HUMANOID_BONES
from stylecast.motion.smoothing import CorrectionFilter
from stylecast.motion.words import BlendSettings
from tests.footlock_motion import (J, SK, ON_INPUT_ANKLES, ON_INPUT_PATH, STANCE, crouched, horizontal_speed, restyled,
                                   spread, stepping)


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
        assert slide.max() < settings.stance_rate + 1e-3  # with it: still (within any creep a stance allows)
        for side, (upper, lower, foot, toes) in enumerate(LEGS):
            for k, bone in ((1, lower), (2, foot)):
                length = np.linalg.norm(p_out[:, side, k] - p_out[:, side, k - 1], axis=-1)
                np.testing.assert_allclose(length, np.linalg.norm(SK.offsets[bone]), atol=1e-9)
    # Without the stance offset the planted foot is the input's own, within a millimetre
    # (positions in cm), the ball of the foot too (foot orientation and toes from the input).
    err = np.linalg.norm(p_out[:, :, 2:4] - p_in[:, :, 2:4], axis=-1)[contacts]
    assert err.max() < 0.1


def test_a_restyled_stance_is_kept_and_a_planted_foot_stays_in_it():
    roots, q = stepping(240)
    standing = np.tile(q[:1], (240, 1, 1))  # both feet planted all the time
    roots = np.tile(roots[:1], (240, 1))
    angle = np.where(np.arange(240) < 120, 4.0, 0.0)  # wide for two seconds, then narrow again
    out_in = spread(standing, angle)
    p_in, _, _ = leg_chain(roots, standing, SK.offsets)
    p_raw, _, _ = leg_chain(roots, out_in, SK.offsets)

    def width(p):
        return np.abs(p[:, 0, 2, 0] - p[:, 1, 2, 0])

    def locked(settings):
        lock = FootLock(SK, settings=settings)
        contacts = lock.push(roots, standing)
        new_roots, out = lock.apply(0, roots, standing, out_in)
        assert contacts[1:].all()
        p_out = leg_chain(new_roots, out, SK.offsets)[0]
        return width(p_out), horizontal_speed(p_out[1:, :, 2]).max()

    # the restyle spreads the feet, each within the stance's cap
    assert 10.0 < (width(p_raw) - width(p_in))[:120].min() < 2 * STANCE.stance_cap
    (kept, kept_slide), (lost, lost_slide) = locked(STANCE), locked(ON_INPUT_ANKLES)
    np.testing.assert_allclose(kept[:120], width(p_raw)[:120], atol=0.05)  # the wide stance is kept
    np.testing.assert_allclose(lost[1:], width(p_in)[1:], atol=0.05)  # locked on the input's ankles: undone
    # When the restyle narrows the stance again the planted feet stay where they stand (a
    # stance changes by a step), and neither lock ever slides a planted foot.
    np.testing.assert_allclose(kept[120:], kept[119], atol=1e-6)
    assert max(kept_slide, lost_slide) < 1e-6
    # The known-bad case, a lock that follows the restyled stance while planted (0.01 cm a
    # frame, the previous setting): the feet creep, and the checks above see it.
    crept, crept_slide = locked(replace(STANCE, stance_rate=0.01))
    assert crept[-1] < crept[119] - 2 * 120 * 0.01 + 0.05 and crept_slide > 0.009


def test_a_style_may_stand_where_the_performer_stands_and_still_keep_its_stance_walking():
    """``stance_standing``: the share of the stance's place kept while the performer stands
    (the multistyle model towards active keeps none: its restyled standing stance is wider
    than any real active take's). A standing figure restyled 12 cm wider: kept all of it
    (the default), none or half; walking, all of it whatever the share; a foot that landed
    walking stays where it landed when the performer stops, until it lifts."""
    frames = 90
    ankle = np.zeros((frames, 2, 3))
    own = (ankle, ankle + [0.0, 0.0, 12.0])
    wider = ankle + [[[6.0, 0.0, 0.0], [-6.0, 0.0, 0.0]]]
    restyled_feet = (wider, wider + [0.0, 0.0, 12.0])
    planted = np.ones((frames, 2))
    still = np.zeros((frames, 3))
    walking = np.outer(np.arange(frames), [0.0, 0.0, 1.5])  # 1.5 cm a frame, past MOVING_SPEED

    def offsets(standing, roots, weights=planted):
        return StanceOffset(replace(STANCE, stance_standing=standing)).track(0, own, restyled_feet, weights,
                                                                             roots=roots)[:, :, 0]

    np.testing.assert_allclose(offsets(1.0, still), [[6.0, -6.0]] * frames)  # the restyled stance
    np.testing.assert_allclose(offsets(0.0, still), 0.0)  # the performer's own
    np.testing.assert_allclose(offsets(0.5, still), [[3.0, -3.0]] * frames)
    landing = planted.copy()
    landing[:40] = 0.0  # free for 40 frames, then planted
    # walking, all of it (from the stream's second frame: its first has no speed yet)
    np.testing.assert_allclose(offsets(0.0, walking, landing)[1:], [[6.0, -6.0]] * (frames - 1))
    # free while walking, landing as the performer stops: the foot stands where it landed
    stopping = walking.copy()
    stopping[45:] = walking[45]
    stopped = offsets(0.0, stopping, landing)
    assert stopped[40, 0] > 5.9  # landed at (nearly) all of the stance, the speed still walking's
    np.testing.assert_allclose(stopped[40:], np.broadcast_to(stopped[40], (frames - 40, 2)), atol=1e-12)  # held
    # In between the paces, a share between: the low-passed speed is 0.6 cm a frame
    slow = offsets(0.0, np.outer(np.arange(frames), [0.0, 0.0, 0.6]), landing)
    np.testing.assert_allclose(slow[-1], [3.0, -3.0], atol=1e-6)


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


@pytest.mark.parametrize("paced, sight, feet", [(False, 4, "input"), (True, 4, "input"), (False, 1, "input"),
                                               (True, 1, "input"), (True, 4, "path"), (True, 1, "path")])
def test_streaming_a_frame_at_a_time_equals_the_whole_clip(paced, sight, feet):
    """Applied ``sight`` frames behind the newest pushed (a stream's delay), as for the whole
    clip pushed at once: with a sight short of the ramp the lock foresees what the whole
    clip would show it, and reads nothing of it."""
    roots, q = stepping(180)
    out_in = restyled(q)
    settings = FEET[feet]
    mix = None
    if paced:  # gliding on at 0.3 cm a frame (slow enough to plant), slowed to 0.8 of it as the restyle fades in,
        # with the arms' swing, the hips' bob and the hands' swing across scaled as well (``GaitAmplitude``)
        roots = roots + np.outer(0.3 * np.arange(len(q)), [0.0, 0.0, 1.0])
        settings = replace(settings, pace=((0.3, 0.24),), arm_swing=((0.3, 0.5),), hips_bob=((0.3, 0.6),),
                           arm_across=((0.3, 0.0),))
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
    one lock alone takes its feet on Python floats). Six
    performers: three body sizes, all three locks (two stances of different settings), two
    gliding off (the floor step, not the lock) at a slower pace."""
    roots, q = stepping(200)
    glide = roots.copy()
    glide[100:, 2] = 5.0 * np.arange(100)
    performers = [(SK, ON_INPUT_ANKLES, roots, restyled(q)),
                  (SK.with_offsets(SK.offsets * 0.85), ON_INPUT_ANKLES, roots * [1, 0.85, 1], restyled(q, 20.0)),
                  # the hands' swing across replaced, on a larger body gliding off, none of the stance's place
                  # kept standing
                  (SK.with_offsets(SK.offsets * 1.1), replace(STANCE, arm_across=((2.0, 0.0),), stance_standing=0.0),
                   glide * [1, 1.1, 1], restyled(q)),
                  (SK, replace(ON_INPUT_ANKLES, pace=((2.0, 1.5),)), glide, crouched(q)),  # and a pace
                  # a stance of other settings beside the first, half its place kept standing
                  (SK, replace(OTHER_STANCE, stance_standing=0.5), roots, restyled(q, 20.0)),
                  # swings on the input's path, the arms' swing, the hips' bob, the swing across, a
                  # raised hand's sway scaled, the elbows' bend, the hands carried forward, still and
                  # waving arms held, a waving elbow given back, the knees' bend, the elbows carried,
                  # the lean (``GaitAmplitude``)
                  (SK, replace(ON_INPUT_PATH, pace=((2.0, 1.5),), arm_swing=((2.0, 0.5), (5.0, 1.5)),
                               hips_bob=((2.0, 0.5),), arm_across=((2.0, 0.0), (5.0, 0.5)),
                               wave_sway=((0.0, 1.5), (5.0, 1.0)), raise_sway=((0.0, 0.5), (5.0, 1.0)),
                               elbow_bend=((2.0, 0.0, 0.0), (5.0, 1.0, 60.0)),
                               arm_forward=((2.0, 0.0, 0.0), (5.0, 0.5, 20.0)), still_arms=((0.0, 0.8),),
                               waving_arms=((0.0, 0.6),), waving_elbows=((0.0, 0.5),),
                               knee_bend=((2.0, 1.0, 25.0), (5.0, 0.5, 40.0)),
                               elbow_forward=((2.0, 1.0, 15.0), (5.0, 0.5, 5.0)),
                               performer_lean=((2.0, 1.0), (5.0, 0.5))), glide,
                   restyled(q))]
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
    assert together[5].amplitude._moving == [True] * 17  # the gait amplitude was exercised
    assert together[2].amplitude._moving == [False, False, True] + [False] * 14
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


def test_a_stance_let_go_over_8_frames_does_not_snap_a_lifting_foot_to_its_swing(bandai_root):
    """The multistyle model made active, a held-out turning walk through the stream with
    its stance lock: by lift-off the restyled swing foot is centimetres from where the
    stance held it, and let go over 4 frames (the known-bad case) the foot jumps that gap:
    the feet's largest one-frame jerk 1.72x the input's; over the stance's 8 frames 0.95x
    (the file shipped before 2026-11-30: 2.1x and 1.4x)."""
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

    assert feet_pops(8) < 1.2
    assert feet_pops(4) > 1.5


def test_a_rig_that_is_not_the_humanoid_is_refused():
    from stylecast.motion.skeleton import Skeleton

    with pytest.raises(ValueError):
        FootLock(Skeleton(("a", "b"), (-1, 0), np.zeros((2, 3))))


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
    assert slides["at the aim"] < 1e-6  # and never slides
    assert slides["following the fade"] > 0.05  # the known-bad cases: following the fade slides,
    assert widths["input's"][fade] - own[fade] < (wanted[fade] - own[fade]) / 4  # and holding the input's keeps it


def test_a_landing_foot_stands_where_its_restyled_swing_comes_to_rest():
    """A stance offset frozen where the lock starts to blend in, ``ramp`` frames before
    touch-down (the known-bad case, the previous capture), keeps the swinging foot's
    offset: the multistyle model's feminine walks froze a foot 7.9 cm inward of the input's
    and the ankles crossed. Settling eases the offset to a stop through the blend-in, so
    the foot stands near where its restyled swing comes to rest; from the full lock on it
    holds, through the let-go too."""
    ramp, release, contact = 4, 8, 16
    weights = np.concatenate([np.zeros(10), lock_kernel(ramp, release, release)[release:][::-1][:ramp],
                              np.ones(contact), lock_kernel(ramp, release, release)[:release][::-1], np.zeros(4)])
    n = len(weights)
    landing = np.array([-7.5, -4.5, -2.8, -2.2])  # the restyled left foot's offset, decelerating as it lands
    across = np.full(n, -7.5)  # ...inward of the input's (x +5), swinging across before and after
    across[10:10 + ramp] = landing
    across[10 + ramp:10 + ramp + contact] = -2.0  # where it stands through the contact
    own_ankle = np.zeros((n, 2, 3))
    own_ankle[:, 0, 0], own_ankle[:, 1, 0] = 5.0, -5.0
    own = (own_ankle, own_ankle + [0.0, 0.0, 12.0])
    ankle = own_ankle.copy()
    ankle[:, 0, 0] += across
    locked = np.zeros((n, 2))
    locked[:, 0] = weights
    planted = slice(10 + ramp, 10 + ramp + contact + release)  # full lock, then letting go

    def offsets(settle):
        stance = StanceOffset(replace(STANCE, stance_settle=settle))
        return stance.track(0, own, (ankle, ankle + [0.0, 0.0, 12.0]), locked)[:, 0, 0]

    frozen, settled = offsets(False), offsets(True)
    np.testing.assert_allclose(frozen[10:planted.stop], -7.5)  # the known-bad: the swing's offset, kept
    held = settled[planted]
    np.testing.assert_allclose(held, held[0], atol=1e-12)  # still from the full lock through the let-go
    assert -4.8 < held[0] < -4.0  # 3 cm nearer where the foot comes to rest (-2) than the swing's
    steps = np.abs(np.diff(settled[10:10 + ramp]))  # through the blend-in, before the full lock
    assert np.all(np.diff(steps) < 0) and steps[-1] < 0.3  # easing to a stop, not stopping dead
    np.testing.assert_allclose(settled[:10], -7.5)  # free before the lock, as before


def test_a_foot_planted_through_the_lead_in_stands_at_the_restyled_stances_mean():
    """A standing take's feet are planted from its first frame to its last, so the stance
    taken at the end of an offline clip's mirrored lead-in is kept for the whole take. The
    restyled stance wanders while a performer stands (the known-bad case: the lead-in's last
    frame happens to stand on the input's ankle, 0 cm, where the restyle stands 3 cm out on
    average): the last frame's offset is then the take's stance. With ``stance_lead_mean`` the
    foot stands at the mean of the lead-in's offsets, and holds it once the clip is shown.
    A foot that swings through the lead-in follows it frame by frame, as before."""
    lead, shown = 40, 20
    n = lead + shown
    wander = 3.0 + 2.0 * np.sin(np.arange(n) * 2 * np.pi / 20.0)  # mean 3 cm out over whole periods
    wander[lead - 1] = 0.0  # the lead-in's last frame: on the input's ankle
    own_ankle = np.zeros((n, 2, 3))
    own_ankle[:, 0, 0], own_ankle[:, 1, 0] = 5.0, -5.0
    own = (own_ankle, own_ankle + [0.0, 0.0, 12.0])
    ankle = own_ankle.copy()
    ankle[:, 0, 0] += wander  # the left foot's restyled stance
    ankle[:, 1, 0] -= wander  # the right foot's
    weights = np.ones((n, 2))
    weights[:, 1] = 0.0  # the right foot swings throughout

    def offsets(lead_mean):
        stance = StanceOffset(replace(STANCE, stance_lead_mean=lead_mean))
        stance.free_until = lead
        return stance.track(0, own, (ankle, ankle + [0.0, 0.0, 12.0]), weights)[:, :, 0]

    last, mean = offsets(False), offsets(True)
    np.testing.assert_allclose(last[lead:, 0], 0.0, atol=1e-12)  # the known-bad: one frame's stance, kept
    np.testing.assert_allclose(mean[lead:, 0], mean[lead, 0], atol=1e-12)  # held once the clip is shown
    np.testing.assert_allclose(mean[lead, 0], wander[:lead].mean(), atol=1e-9)  # the lead-in's mean
    assert mean[lead, 0] > 2.8
    np.testing.assert_allclose(mean[:, 1], -wander)  # a swinging foot follows frame by frame
    np.testing.assert_allclose(last[:, 1], -wander)


def test_towards_elderly_a_swing_on_the_inputs_path_keeps_one_hump(bandai_root):
    """The multistyle model made elderly (pace 0.82 in walks), a held-out walk through the
    stream: with its own lock (``path``) a free foot goes along the input's ankle path less
    its pace shift, so its speed keeps the input's one hump through each swing. The
    known-bad case, the restyled swing with the input lock: a lifting foot crosses the gap
    to the restyled swing in the 4 frames of the release, then slows, and every swing dips
    (``metrics.swing_dips``; the real walks of every style: none of 777)."""
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
    r = Restyler.load("multistyle").with_performer_style("normal").for_target("elderly")
    own = feet_for(AUTO_FEET, r)
    assert own.swing_path and own.pace  # the model's own lock for elderly, at the style's pace
    jerk_in = M.jerk(M.world_positions(inp, roots, humanoid.skeleton)).max()

    def swings(contacts):
        out, moved = restyle_rotations(inp, r.restyle_words, contacts=contacts, roots=roots,
                                       skeleton=humanoid.skeleton, **stream_settings_of(r))
        p = M.world_positions(out, moved, humanoid.skeleton)
        return M.swing_dips(p), M.jerk(p).max() / jerk_in

    dips, pops = swings(own)
    dips_restyled, _ = swings(replace(own, swing_path=False))
    assert len(dips) >= 4 and dips.sum() == 0 and pops < 1.5
    assert dips_restyled.mean() >= 0.75
