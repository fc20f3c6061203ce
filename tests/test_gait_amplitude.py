"""The style's arm swing and hip bob (models/gait_amplitude.py, motion/footlock/
``GaitAmplitude``): the tables are what the training clips measure, a walking stream's arms
swing and hips bob by the style's ratios while a standing one's (a wave) are left alone, the
restyle's own change of the arms is kept, a clip at once equals a stream a frame at a time,
and a live change of style never steps the arms."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stylecast.models import data as D
from stylecast.models.gait_amplitude import (ARM_ACROSS_REPLACED, ARM_FORWARD_SHARE, ARM_FORWARDS, ARM_SWING_TRIM,
                                             ARM_SWINGS, ELBOW_BEND_SHARE, ELBOW_BENDS, ELBOW_FORWARD_SHARE,
                                             ELBOW_FORWARDS, HIPS_BOBS, KNEE_BEND_SHARE, KNEE_BENDS, LEAN_SHARE,
                                             RAISED_SWAY_GAIN, STILL_ARM_SHARE, WAVING_ARM_SHARE, WAVING_ELBOW_SHARE,
                                             across_points, amplitude_points, amplitudes, elbow_forward_points,
                                             elbow_points, forward_points, knee_points, lean_points,
                                             measure_arm_forwards,
                                             measure_arm_swings, measure_elbow_bends, measure_elbow_forwards,
                                             measure_hips_bobs, measure_knee_bends, still_points, sway_points,
                                             waving_elbow_points, waving_points)
from stylecast.models.metrics import arm_swing, hips_bob, hips_yaw, world_positions
from stylecast.models.pace import PACES
from stylecast.motion import rotations as rot
from stylecast.motion.footlock import FEET, ContactSettings, FootLock, GaitAmplitude
from stylecast.motion.footlock.across import LOWER_ARM_INDEX, UPPER_ARM_INDEX, arm_places, hand_across, move_across
from stylecast.motion.footlock.amplitude import (ACROSS_INPUT_SHARE, MAX_SWING_GAIN, RAISED_GATE_CM, SWING_INDEX,
                                                 WAVING_GATE_CM, amplitude_frames)
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default
from stylecast.motion.smoothing import smoothstep

DATA = D.default_data_dir()
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason=f"the shared Bandai data is not at {DATA}")
J = len(HUMANOID_BONES)
UPPER_ARM = HUMANOID_BONES.index("LeftUpperArm")
SKELETON = humanoid_skeleton_default()


@needs_data
@pytest.mark.parametrize("table, measure", [(ARM_SWINGS, measure_arm_swings), (HIPS_BOBS, measure_hips_bobs),
                                            (ELBOW_BENDS, measure_elbow_bends), (ARM_FORWARDS, measure_arm_forwards),
                                            (KNEE_BENDS, measure_knee_bends),
                                            (ELBOW_FORWARDS, measure_elbow_forwards)])
def test_the_amplitude_tables_are_what_the_training_clips_measure(table, measure):
    measured = measure(D.list_files(DATA))
    assert set(measured) == set(table)
    for style, (walks, runs) in measured.items():
        assert table[style] == pytest.approx((walks, runs), abs=0.0051), style


def arm_swing_points(source, target):
    return amplitude_points(ARM_SWINGS, source, target)


def test_amplitude_points_give_the_target_mix_over_the_source_at_the_source_paces():
    same = arm_swing_points("normal", {"normal": 1.0})
    assert [g for _, g in same] == pytest.approx([1.0, 1.0])
    assert [v for v, _ in same] == pytest.approx([PACES["normal"][0] / 60, PACES["normal"][1] / 60])
    elderly = arm_swing_points("normal", {"elderly": 1.0})
    assert [g for _, g in elderly] == pytest.approx([7.09 / 13.84, 14.64 / 14.63])
    half = arm_swing_points("normal", {"elderly": 0.5, "youthful": 0.5})
    assert half[0][1] == pytest.approx((7.09 + 21.33) / 2 / 13.84)
    from_elderly = arm_swing_points("elderly", {"normal": 1.0})  # any source: at its own paces
    assert from_elderly[0] == pytest.approx((PACES["elderly"][0] / 60, 13.84 / 7.09))
    assert arm_swing_points("normal", {"dancing": 1.0}) == () and arm_swing_points("robot", {"normal": 1.0}) == ()
    assert amplitudes("normal", {"elderly": 1.0})["hips_bob"][0][1] == pytest.approx(0.69 / 1.28)


def test_a_trimmed_style_swings_its_trimmed_share_as_the_target_and_only_then():
    style = next(iter(ARM_SWING_TRIM))
    walks, runs = ARM_SWING_TRIM[style]
    points = amplitudes("normal", {style: 1.0})["arm_swing"]
    assert [g for _, g in points] == pytest.approx([walks * ARM_SWINGS[style][0] / ARM_SWINGS["normal"][0],
                                                   runs * ARM_SWINGS[style][1] / ARM_SWINGS["normal"][1]])
    assert points[0][1] < arm_swing_points("normal", {style: 1.0})[0][1]  # the trim is used
    # a mix trims its share; a trimmed performer's own swing is what it measures
    half = amplitudes("normal", {style: 0.5, "normal": 0.5})["arm_swing"][0][1]
    assert half == pytest.approx((walks * ARM_SWINGS[style][0] + ARM_SWINGS["normal"][0]) / 2 / ARM_SWINGS["normal"][0])
    assert amplitudes(style, {"normal": 1.0})["arm_swing"] == arm_swing_points(style, {"normal": 1.0})
    assert amplitudes(style, {style: 1.0})["arm_swing"][0][1] == pytest.approx(walks)


def test_across_points_replace_the_named_styles_share_at_the_source_paces():
    walks, runs = ARM_ACROSS_REPLACED["youthful"]
    points = across_points("normal", {"youthful": 1.0})
    assert np.asarray(points) == pytest.approx(np.array([[PACES["normal"][0] / 60, 1.0 - walks],
                                                         [PACES["normal"][1] / 60, 1.0 - runs]]))
    # walks and runs apart: a style may replace its runs' alone (the line between them ramps)
    assert [kept for _, kept in across_points("normal", {"feminine": 1.0})] == pytest.approx(
        [1.0 - share for share in ARM_ACROSS_REPLACED["feminine"]])
    # a style not named keeps its own across swing; a mix replaces its share
    assert across_points("normal", {"elderly": 1.0}) == ()
    assert across_points("normal", {"youthful": 0.5, "elderly": 0.5})[0][1] == pytest.approx(1.0 - walks / 2)
    assert across_points("robot", {"youthful": 1.0}) == ()  # a source of unknown paces: none
    assert amplitudes("normal", {"youthful": 1.0})["arm_across"] == points


def test_lean_points_take_the_named_styles_share_at_the_source_paces():
    walks, runs = LEAN_SHARE["active"]
    points = lean_points("normal", {"active": 1.0})
    assert np.asarray(points) == pytest.approx(np.array([[PACES["normal"][0] / 60, walks],
                                                         [PACES["normal"][1] / 60, runs]]))
    assert lean_points("normal", {"elderly": 1.0}) == ()  # a style not named keeps the restyle's lean
    assert lean_points("normal", {"active": 0.5, "elderly": 0.5})[0][1] == pytest.approx(walks / 2)
    assert lean_points("robot", {"active": 1.0}) == ()  # a source of unknown paces: none
    assert amplitudes("normal", {"active": 1.0})["performer_lean"] == points


def test_the_gain_is_one_at_rest_and_the_line_through_its_points():
    amplitude = GaitAmplitude(replace(FEET["input"], arm_swing=((2.0, 0.5), (5.0, 1.4)), hips_bob=((2.0, 0.4),)))
    assert amplitude.gains(0.0) == (1.0, 1.0)
    assert amplitude.gains(1.0) == pytest.approx((0.75, 0.7))
    assert amplitude.gains(3.5) == pytest.approx((0.95, 0.4))
    assert amplitude.gains(9.0) == pytest.approx((1.4, 0.4))
    assert GaitAmplitude(FEET["input"]).gains(3.0) == (1.0, 1.0)  # no points: the input's own
    # a bob only lessens (MAX_BOB_GAIN): a style that bobs more keeps the output's own; and a
    # swing grows at most MAX_SWING_GAIN-fold
    assert GaitAmplitude(replace(FEET["input"], hips_bob=((2.0, 3.0),))).gains(2.0) == (1.0, 1.0)
    assert GaitAmplitude(replace(FEET["input"], arm_swing=((2.0, 3.0),))).gains(2.0) == (MAX_SWING_GAIN, 1.0)


def arms_of(amplitude: GaitAmplitude, roots, inputs, outputs, mix=None):
    """The arms ``amplitude`` gives these frames (None: unchanged), the roots' heights as the output's."""
    return amplitude.apply(roots, inputs, outputs, roots[:, 1], mix, SKELETON.offsets)[0]


def swinging(n: int, speed: float, amplitude_deg: float = 20.0, hz: float = 1.0, seed: int = 0):
    """A synthetic stream: roots moving ``speed`` cm a frame along +Z, every bone turned a
    little from the rest pose (random, fixed), the upper arms swinging about X at ``hz``."""
    rng = np.random.default_rng(seed)
    base = rot.exp_map(rng.normal(0, 0.3, (J, 3)))
    t = np.arange(n) / 60.0
    q = np.repeat(base[None], n, axis=0)
    angle = np.radians(amplitude_deg) * np.sin(2 * np.pi * hz * t)
    for k, j in enumerate(SWING_INDEX):
        sign = 1.0 if k < 2 else -1.0  # the arms swing in opposite phase
        q[:, j] = rot.multiply(rot.exp_map(np.outer(sign * angle, [1.0, 0.0, 0.0])), base[j])
    roots = np.stack([np.zeros(n), np.full(n, 100.0), speed * np.arange(n)], axis=1)
    return roots, q


def swing_deg(q: np.ndarray, settled: slice) -> float:
    """The upper arm's swing: half its peak-to-peak angle from its mean pose over ``settled``."""
    arm = q[settled, UPPER_ARM]
    mean = arm.mean(axis=0)
    mean /= np.linalg.norm(mean)
    angle = np.degrees(np.linalg.norm(rot.log_map(rot.multiply(arm, rot.inverse(mean[None]))), axis=-1))
    return float(angle.max())


def test_a_walking_stream_swings_its_arms_by_the_gain_and_a_standing_one_not_at_all():
    settings = replace(FEET["input"], arm_swing=((2.0, 0.5), (5.0, MAX_SWING_GAIN)))
    settled = slice(180, None)
    roots, q = swinging(600, speed=2.0)
    out = arms_of(GaitAmplitude(settings), roots, q, q)
    # the instrument sees the swing as it is where nothing is done...
    assert swing_deg(q, settled) == pytest.approx(20.0, abs=0.1)
    # ...half of it at the walking gain (the low-passed mean keeps ~15 % of a 1 Hz swing, so
    # the swing about the input's mean is a little less than the input's whole swing)
    assert swing_deg(out, settled) == pytest.approx(10.0, abs=1.6)
    fast_roots, _ = swinging(600, speed=5.0)
    faster = arms_of(GaitAmplitude(settings), fast_roots, q, q)
    assert swing_deg(faster, settled) == pytest.approx(20.0 * MAX_SWING_GAIN, abs=2.4)
    # the other bones are the restyle's, untouched (the elbows, which this input holds
    # still, rebuilt from their hinge parts: to rounding)
    elbows = [HUMANOID_BONES.index(b) for b in ("LeftLowerArm", "RightLowerArm")]
    others = np.setdiff1d(np.arange(J), SWING_INDEX + elbows)
    np.testing.assert_array_equal(out[:, others], q[:, others])
    np.testing.assert_allclose(out[:, elbows], q[:, elbows], atol=1e-12)
    # standing (the roots still: a wave, a raise): the arms are the action, left as they are
    still = np.repeat(roots[:1], len(roots), axis=0)
    assert arms_of(GaitAmplitude(settings), still, q, q) is None
    # no swing set: nothing changes either
    assert arms_of(GaitAmplitude(FEET["input"]), roots, q, q) is None


def hanging(n: int, speed: float, swing_deg: float = 20.0, seed: int = 0, hz: float = 1.0, out_deg: float = 10.0):
    """A synthetic walk: roots moving ``speed`` cm a frame along +Z, every bone turned a
    little from the rest pose, the upper arms hanging ``out_deg`` out to their sides (the
    rest pose holds them straight out) and swinging forward and back at ``hz``."""
    rng = np.random.default_rng(seed)
    base = rot.exp_map(rng.normal(0, 0.05, (J, 3)))
    angle = np.radians(swing_deg) * np.sin(2 * np.pi * hz * np.arange(n) / 60.0)
    q = np.repeat(base[None], n, axis=0)
    for side, j in zip((-1.0, 1.0), UPPER_ARM_INDEX):
        hang = rot.exp_map(np.array([0.0, 0.0, side * np.radians(90.0 - out_deg)]))
        q[:, j] = rot.multiply(rot.exp_map(np.outer(side * angle, [1.0, 0.0, 0.0])), rot.multiply(hang, base[j]))
    return np.stack([np.zeros(n), np.full(n, 100.0), speed * np.arange(n)], axis=1), q


def across_sway(q: np.ndarray, settled: slice = slice(180, None)) -> np.ndarray:
    """cm, (left, right): each hand's across place against its shoulder, the standard
    deviation about its 1 s running mean over ``settled``."""
    from scipy.ndimage import uniform_filter1d

    x = hand_across(q, SKELETON.offsets)
    return (x - uniform_filter1d(x, 60, axis=0, mode="nearest"))[settled].std(axis=0)


def test_hand_across_reads_the_metrics_axis_and_move_across_moves_the_hand_there():
    """``hand_across`` is forward kinematics' hand against its shoulder joint, across the
    hips' facing as ``models.metrics`` reads it; ``move_across`` moves each hand that far
    across by the upper arm alone, the arm keeping its length."""
    from stylecast.models.metrics import hips_yaw

    roots, q = hanging(120, speed=2.0)
    q[:, 0] = rot.multiply(rot.exp_map(np.outer(np.linspace(0, 3, 120), [0.0, 1.0, 0.0])), q[:, 0])  # turning
    p = world_positions(q, roots, SKELETON)
    yaw = hips_yaw(q)
    for k, side in enumerate(("Left", "Right")):
        rel = p[:, HUMANOID_BONES.index(f"{side}Hand")] - p[:, HUMANOID_BONES.index(f"{side}UpperArm")]
        np.testing.assert_allclose(hand_across(q, SKELETON.offsets)[:, k],
                                   np.cos(yaw) * rel[:, 0] - np.sin(yaw) * rel[:, 2], atol=1e-9)
    shift = np.random.default_rng(1).uniform(-4.0, 4.0, (120, 2))
    moved = move_across(q, SKELETON.offsets, shift)
    got = hand_across(moved, SKELETON.offsets) - hand_across(q, SKELETON.offsets)
    np.testing.assert_allclose(got, shift, atol=1e-9)
    others = np.setdiff1d(np.arange(J), UPPER_ARM_INDEX)
    np.testing.assert_array_equal(moved[:, others], q[:, others])
    p_moved = world_positions(moved, roots, SKELETON)
    for side in ("Left", "Right"):  # the arm keeps its length
        hand, shoulder = HUMANOID_BONES.index(f"{side}Hand"), HUMANOID_BONES.index(f"{side}UpperArm")
        np.testing.assert_allclose(np.linalg.norm(p_moved[:, hand] - p_moved[:, shoulder], axis=-1),
                                   np.linalg.norm(p[:, hand] - p[:, shoulder], axis=-1), atol=1e-9)
    np.testing.assert_allclose(move_across(q, SKELETON.offsets, np.zeros((120, 2))), q, atol=1e-12)


def test_a_walking_stream_swings_its_hands_across_as_a_share_of_the_input_and_a_standing_one_not_at_all():
    """A walk swinging its hands 4 cm across, restyled to swing them 6 cm more: with the
    output's across swing replaced (kept share 0) each hand sits at the low-pass of the
    restyled across place plus ACROSS_INPUT_SHARE of the input's swing about its own
    low-pass; with half kept, about halfway; standing (a wave) and without points nothing
    changes, and only the upper arms turn."""
    from scipy.signal import lfilter, lfilter_zi

    from stylecast.motion.smoothing import triple_pole

    roots, straight = hanging(600, speed=2.0)
    swing = np.outer(np.sin(2 * np.pi * np.arange(600) / 60.0), [1.0, -1.0])
    q = move_across(straight, SKELETON.offsets, 4.0 * swing)
    restyled = move_across(q, SKELETON.offsets, 6.0 * swing)
    own, made = across_sway(q), across_sway(restyled)
    assert np.all(own > 2.0) and np.all(made > own + 3.5)  # the instrument sees the added swing

    def across_of(kept, r=roots):
        amplitude = GaitAmplitude(replace(FEET["input"], arm_across=((2.0, kept),)))
        return amplitude.apply(r, q, restyled, r[:, 1], None, SKELETON.offsets)[0]

    b, a = triple_pole(FEET["input"].amplitude_tau)

    def low_pass(x):
        return lfilter(b, a, x, axis=0, zi=lfilter_zi(b, a)[:, None] * x[:1])[0]

    into, out = hand_across(q, SKELETON.offsets), hand_across(restyled, SKELETON.offsets)
    replaced = across_of(0.0)
    np.testing.assert_allclose(hand_across(replaced, SKELETON.offsets),
                               low_pass(out) + ACROSS_INPUT_SHARE * (into - low_pass(into)), atol=1e-6)
    assert np.all(across_sway(replaced) < 0.5 * own)
    assert np.all(np.abs(across_sway(across_of(0.5)) - (made + across_sway(replaced)) / 2) < 0.2 * made)
    others = np.setdiff1d(np.arange(J), UPPER_ARM_INDEX)
    np.testing.assert_array_equal(replaced[:, others], restyled[:, others])
    assert across_of(1.0) is None
    assert across_of(0.0, np.repeat(roots[:1], len(roots), axis=0)) is None


def waving(n: int, speed: float = 0.0, sway_deg: float = 20.0, hz: float = 2.0, seed: int = 0):
    """A synthetic wave of both hands: roots moving ``speed`` cm a frame along +Z, every bone
    turned a little from the rest pose, each upper arm pointing forward and its forearm up
    (the hand 25 cm over the elbow), tilting side to side by ``sway_deg`` at ``hz``."""
    rng = np.random.default_rng(seed)
    base = rot.exp_map(rng.normal(0, 0.05, (J, 3)))
    tilt = np.radians(sway_deg) * np.sin(2 * np.pi * hz * np.arange(n) / 60.0)
    q = np.repeat(base[None], n, axis=0)
    for side, upper, lower in zip((1.0, -1.0), UPPER_ARM_INDEX, LOWER_ARM_INDEX):  # rest: +X (left) / -X (right)
        q[:, upper] = rot.exp_map(np.array([0.0, -side * np.pi / 2, 0.0]))  # to +Z, forward
        q[:, lower] = rot.multiply(rot.exp_map(np.outer(-side * tilt, [1.0, 0.0, 0.0])),
                                   rot.exp_map(np.array([0.0, 0.0, side * np.pi / 2])))  # up, tilting across
    return np.stack([np.zeros(n), np.full(n, 100.0), speed * np.arange(n)], axis=1), q


def test_a_raised_hand_sways_across_by_the_waves_or_the_raises_gain_and_a_hanging_or_walking_one_not_at_all():
    """A standing wave of both hands restyled to sway less, and a raise (the performer's
    raised hands still) restyled to sway: each hand sits at the low-pass of its restyled
    across place plus g times the restyle's sway about it (to first order: ``sway_turns``),
    g the wave's gain where the performer waves (once its sway's low-pass has risen past
    the gate) and the raise's where it does not; hanging hands standing, and the wave at the
    walking pace, do not move; only the upper arms turn."""
    from scipy.signal import lfilter, lfilter_zi

    from stylecast.motion.smoothing import triple_pole

    roots, q = waving(600, sway_deg=10.0)
    performed, still = waving(600, sway_deg=20.0)[1], waving(600, sway_deg=0.0)[1]
    assert np.all(arm_places(q, SKELETON.offsets).raised() > RAISED_GATE_CM[1])  # the hands are raised throughout

    def swayed(wave, lift, r=roots, frames=q, inputs=performed):
        amplitude = GaitAmplitude(replace(FEET["input"], wave_sway=((0.0, wave), (2.0, 1.0)),
                                          raise_sway=((0.0, lift), (2.0, 1.0))))
        return amplitude.apply(r, inputs, frames, r[:, 1], None, SKELETON.offsets)[0]

    b, a = triple_pole(FEET["input"].amplitude_tau)
    out = hand_across(q, SKELETON.offsets)
    level = lfilter(b, a, out, axis=0, zi=lfilter_zi(b, a)[:, None] * out[:1])[0]
    settled = slice(180, None)  # the performer's sway and the gain's low-pass past the gate (WAVING_GATE_CM)
    wider = swayed(1.6, 0.5)
    swing = np.abs(out - level).max()
    np.testing.assert_allclose(hand_across(wider, SKELETON.offsets)[settled], (level + 1.6 * (out - level))[settled],
                               atol=0.05 * swing)
    assert np.all(across_sway(wider) > 1.4 * across_sway(q))  # the instrument sees it
    raised = swayed(1.6, 0.5, inputs=still)  # a raise: the raise's gain
    np.testing.assert_allclose(hand_across(raised, SKELETON.offsets)[settled], (level + 0.5 * (out - level))[settled],
                               atol=0.05 * swing)
    others = np.setdiff1d(np.arange(J), UPPER_ARM_INDEX)
    np.testing.assert_array_equal(wider[:, others], q[:, others])
    standing, hanging_arms = hanging(600, speed=0.0)
    np.testing.assert_allclose(swayed(1.6, 0.5, standing, hanging_arms, hanging_arms), hanging_arms, atol=1e-12)
    walking = np.stack([np.zeros(600), np.full(600, 100.0), 2.0 * np.arange(600)], axis=1)
    np.testing.assert_allclose(swayed(1.6, 0.5, walking)[180:], q[180:], atol=1e-6)  # the gains eased to 1


def test_a_sway_turn_moves_a_hand_across_to_first_order_and_never_further_than_asked():
    """``sway_turns``: a hanging hand, one raised straight up, or one held straight forward at
    shoulder height (as in a feminine raise: a turn about the forward axis alone could not
    move it across at all) moves across by the shift to first order; in any pose, arms held
    nearly straight across among them, no hand moves further than the shift (where
    ``move_across``'s exact move swings a hand held nearly straight across far square to
    it)."""
    from stylecast.motion.footlock.across import sway_turns, turn_upper_arms

    shift = np.full((1, 2), 2.0)
    for pose in (hanging(1, 0.0)[1], waving(1)[1]):
        places = arm_places(pose, SKELETON.offsets)
        turned = turn_upper_arms(pose, places.parent, sway_turns(places, shift))
        np.testing.assert_allclose(hand_across(turned, SKELETON.offsets) - places.across(), shift, rtol=0.05)
    rng = np.random.default_rng(3)
    poses = rot.exp_map(rng.normal(0.0, 1.2, (400, J, 3)))
    poses[:200] = rot.identity((200, J))
    for side, j, lower in zip((1.0, -1.0), UPPER_ARM_INDEX, LOWER_ARM_INDEX):
        # arms held nearly straight across (1-5 degrees down) and straight forward
        poses[:100, j] = rot.exp_map(np.outer(-side * np.radians(rng.uniform(1.0, 5.0, 100)), [0.0, 0.0, 1.0]))
        poses[100:200, j] = rot.exp_map(np.tile([0.0, -side * np.pi / 2, 0.0], (100, 1)))
        poses[:200, lower] = rot.identity((200,))
    shifts = rng.uniform(-5.0, 5.0, (400, 2))
    places = arm_places(poses, SKELETON.offsets)
    turned = arm_places(turn_upper_arms(poses, places.parent, sway_turns(places, shifts)), SKELETON.offsets)
    moved = np.linalg.norm(turned.hand - places.hand, axis=-1)
    assert np.all(moved <= np.abs(shifts) * 1.001 + 1e-9)
    assert np.all(moved[:100] < 0.2 * np.abs(shifts[:100]))  # held nearly straight across: hardly moved at all
    across = np.sum((turned.hand - places.hand) * places.left, axis=-1)
    np.testing.assert_allclose(across[100:200], shifts[100:200], rtol=0.05)  # held straight forward: all of it
    straight = move_across(poses[:100], SKELETON.offsets, np.full((100, 2), -2.0))  # the exact move, for contrast
    assert np.linalg.norm(arm_places(straight, SKELETON.offsets).hand - places.hand[:100], axis=-1).max() > 5.0


def test_the_gates_are_smooth_steps():
    for edges in (RAISED_GATE_CM, WAVING_GATE_CM):
        low, high = edges
        share = smoothstep(np.array([-20.0, low, (low + high) / 2, high, 30.0]), *edges)
        assert share == pytest.approx([0.0, 0.0, 0.5, 1.0, 1.0])
        x = np.linspace(low - 1, high + 1, 2001)
        steps = np.diff(smoothstep(x, *edges))
        assert np.all(steps >= 0) and np.abs(np.diff(steps)).max() < 1e-5  # no kink


def test_sway_points_give_the_mix_gains_standing_and_one_at_the_source_walking_pace():
    style = next(iter(RAISED_SWAY_GAIN))
    wave, lift = RAISED_SWAY_GAIN[style]
    for kind, gain in enumerate((wave, lift)):
        points = sway_points("normal", {style: 1.0}, kind)
        if gain == 1.0:  # the restyle's own
            assert points == ()
            continue
        assert np.asarray(points) == pytest.approx(np.array([[0.0, gain], [PACES["normal"][0] / 60, 1.0]]))
        assert sway_points("normal", {style: 0.5, "elderly": 0.5}, kind)[0][1] == pytest.approx((gain + 1.0) / 2)
        amplitude = GaitAmplitude(replace(FEET["input"], raise_sway=points))
        assert amplitude._raise.at(0.0) == pytest.approx(gain) and amplitude._raise.at(PACES["normal"][0] / 60) == 1.0
    assert sway_points("normal", {"elderly": 1.0}, 1) == () and sway_points("robot", {style: 1.0}, 1) == ()
    chosen = amplitudes("normal", {style: 1.0})
    assert (chosen["wave_sway"], chosen["raise_sway"]) == (sway_points("normal", {style: 1.0}, 0),
                                                          sway_points("normal", {style: 1.0}, 1))


def test_elbow_points_take_the_named_styles_share_of_their_own_bend_at_the_source_paces():
    style = next(s for s, (_, runs) in ELBOW_BEND_SHARE.items() if runs > 0)
    walks, runs = ELBOW_BEND_SHARE[style]
    points = elbow_points("normal", {style: 1.0})
    walk_bend = ELBOW_BENDS[style][0] if walks else 0.0  # a share of none asks for no bend
    assert np.asarray(points) == pytest.approx(np.array([[PACES["normal"][0] / 60, walks, walk_bend],
                                                         [PACES["normal"][1] / 60, runs, ELBOW_BENDS[style][1]]]))
    # a mix with a style that keeps the restyle's bend takes half the share, of the same bend
    half = elbow_points("normal", {style: 0.5, "feminine": 0.5})
    assert half[1][1:] == pytest.approx((runs / 2, ELBOW_BENDS[style][1]))
    assert "feminine" not in ELBOW_BEND_SHARE and elbow_points("normal", {"feminine": 1.0}) == ()
    # two styles that take theirs: all of the share, the bends weighed by the mix
    other = next(o for o, (_, r) in ELBOW_BEND_SHARE.items() if r == runs and o != style)
    mixed = elbow_points("normal", {style: 0.25, other: 0.75})
    assert mixed[1][1:] == pytest.approx((runs, 0.25 * ELBOW_BENDS[style][1] + 0.75 * ELBOW_BENDS[other][1]))
    assert elbow_points("robot", {style: 1.0}) == ()  # a source of unknown paces: none
    assert amplitudes("normal", {style: 1.0})["elbow_bend"] == points


def test_knee_points_take_the_named_styles_share_of_their_own_bend_at_the_source_paces():
    style = next(s for s, (walks, runs) in KNEE_BEND_SHARE.items() if walks > 0 and runs > 0)
    walks, runs = KNEE_BEND_SHARE[style]
    points = knee_points("normal", {style: 1.0})
    assert np.asarray(points) == pytest.approx(np.array([[PACES["normal"][0] / 60, walks, KNEE_BENDS[style][0]],
                                                         [PACES["normal"][1] / 60, runs, KNEE_BENDS[style][1]]]))
    keeps = next(s for s in KNEE_BENDS if s not in KNEE_BEND_SHARE)  # keeps the restyle's bend
    assert knee_points("normal", {keeps: 1.0}) == ()
    half = knee_points("normal", {style: 0.5, keeps: 0.5})
    assert half[1][1:] == pytest.approx((runs / 2, KNEE_BENDS[style][1]))
    assert knee_points("robot", {style: 1.0}) == ()  # a source of unknown paces: none
    assert amplitudes("normal", {style: 1.0})["knee_bend"] == points


def test_a_pair_model_takes_its_target_styles_run_bend_and_no_other_amplitude():
    """The shipped pair default (normal -> exhausted) keeps its generator's arm swing and hip
    bob, and its runs take exhausted's elbow bend; the other way (towards normal, a style
    that keeps the restyle's bend) takes nothing."""
    from stylecast.models.restyler import Restyler
    from stylecast.motion.footlock import NO_AMPLITUDES

    pair = Restyler.load()
    own = pair.amplitudes()
    assert own["elbow_bend"] and own["elbow_bend"] == elbow_points("normal", {"exhausted": 1.0})
    assert {name: points for name, points in own.items() if name != "elbow_bend"} == \
        {name: () for name in NO_AMPLITUDES if name != "elbow_bend"}
    assert pair.with_direction("b2a").amplitudes() == NO_AMPLITUDES


def bent_elbows(n: int, speed: float, mean: float, swing: float = 0.3):
    """``swinging`` without the upper arms' swing, each elbow (a hinge about Y) bending
    ``swing`` radians either side of ``mean`` at 1 Hz."""
    roots, q = swinging(n, speed=speed, amplitude_deg=0.0)
    bend = mean + swing * np.sin(2 * np.pi * np.arange(n) / 60.0)
    for joint, sign in ((HUMANOID_BONES.index("LeftLowerArm"), -1.0), (HUMANOID_BONES.index("RightLowerArm"), 1.0)):
        q[:, joint] = rot.exp_map(np.outer(sign * bend, [0.0, 1.0, 0.0]))  # ``HINGES``: left with -Y, right +Y
    return roots, q


def test_a_running_stream_bends_its_elbows_as_the_style_and_a_standing_one_not_at_all():
    """Elbows bent 104 degrees on average while running, the style asking for 70 at the
    running pace: their mean moves to 70, their swing about it stays; at half the share,
    half way; standing (a wave, a raise: the arms are the action), left alone; a hinge
    stays a hinge."""
    from stylecast.motion.hinges import elbow_flexion

    n, settled = 600, slice(240, None)
    run = ((2.0, 0.0, 0.0), (5.0, 1.0, 70.0))
    roots, q = bent_elbows(n, speed=5.0, mean=np.radians(104.0))
    out = arms_of(GaitAmplitude(replace(FEET["input"], elbow_bend=run)), roots, q, q)
    flexion = np.degrees(elbow_flexion(out)[settled])
    assert flexion.mean(axis=0) == pytest.approx([70.0, 70.0], abs=1.0)
    own = np.degrees(elbow_flexion(q)[settled])
    # its swing kept, but for what the low-pass lets into the mean (a triple pole of 15 frames
    # passes 15 % of a 1 Hz swing, which moving the mean adds back, out of phase)
    assert np.ptp(flexion, axis=0) == pytest.approx(np.ptp(own, axis=0), rel=0.2)
    for joint in ("LeftLowerArm", "RightLowerArm"):
        assert np.abs(rot.log_map(out[:, HUMANOID_BONES.index(joint)])[:, [0, 2]]).max() < 1e-9  # a hinge
    half = arms_of(GaitAmplitude(replace(FEET["input"], elbow_bend=((2.0, 0.0, 0.0), (5.0, 0.5, 70.0)))), roots, q, q)
    assert np.degrees(elbow_flexion(half)[settled]).mean() == pytest.approx(87.0, abs=1.0)
    slower_roots, slower = bent_elbows(n, speed=3.5, mean=np.radians(104.0))  # half way between the points
    between = arms_of(GaitAmplitude(replace(FEET["input"], elbow_bend=run)), slower_roots, slower, slower)
    assert np.degrees(elbow_flexion(between)[settled]).mean() == pytest.approx(87.0, abs=1.0)  # the line
    still_roots, still = bent_elbows(n, speed=0.0, mean=np.radians(104.0))
    assert arms_of(GaitAmplitude(replace(FEET["input"], elbow_bend=run)), still_roots, still, still) is None


def test_a_stream_shown_from_its_first_frame_eases_into_a_runs_bend_and_does_not_step_into_it():
    """A stream running from its first frame (no step before it to read a speed from), shown
    from that frame (a live stream): the elbows' bend eases from the restyle's towards the
    style's over the gains' low-pass, each frame's change a small share of the whole. Settled
    on the first step, as an offline clip's unshown lead-in is (and every stream was until
    2026-12-08), the bend steps between the first two frames, all 34 degrees at once."""
    from stylecast.motion.hinges import elbow_flexion

    run = ((2.0, 0.0, 0.0), (5.0, 1.0, 70.0))
    roots, q = bent_elbows(300, speed=5.0, mean=np.radians(104.0), swing=0.0)

    def bend_of(first_frame_shown: bool) -> np.ndarray:
        amplitude = GaitAmplitude(replace(FEET["input"], elbow_bend=run))
        amplitude.first_frame_shown = first_frame_shown
        return np.degrees(elbow_flexion(arms_of(amplitude, roots, q, q))[:, 0])

    live, lead_in = bend_of(True), bend_of(False)
    assert live[0] == pytest.approx(104.0, abs=0.1) and live[-1] == pytest.approx(70.0, abs=1.0)
    assert np.abs(np.diff(live)).max() < 2.0  # degrees a frame, of 34 in all
    assert np.abs(lead_in[1] - lead_in[0]) == pytest.approx(34.0, abs=0.1) and lead_in[-1] == pytest.approx(70.0)

def bent_knees(n: int, speed: float, mean: float, swing: float = 0.5):
    """``swinging`` without the upper arms' swing, each knee (a hinge about X) bending
    ``swing`` radians either side of ``mean`` at 1.5 Hz."""
    roots, q = swinging(n, speed=speed, amplitude_deg=0.0)
    bend = mean + swing * np.sin(2 * np.pi * 1.5 * np.arange(n) / 60.0)
    for joint in ("LeftLowerLeg", "RightLowerLeg"):
        q[:, HUMANOID_BONES.index(joint)] = rot.exp_map(np.outer(bend, [1.0, 0.0, 0.0]))  # ``HINGES``: bent +X
    return roots, q


def test_a_running_stream_bends_its_knees_as_the_style_and_a_standing_one_not_at_all():
    """Knees bent 60 degrees on average while running, the style asking for 48 at the running
    pace: the flexion is scaled (0.8), so its mean goes to 48 and its swing shrinks with it;
    at half the share, half way; standing, left alone; a hinge stays a hinge; and the bend
    ``metrics.knee_bend`` reads from the joints' positions is the hinges' flexion."""
    from stylecast.models.metrics import knee_bend
    from stylecast.motion.hinges import knee_flexion

    n, settled = 600, slice(240, None)
    run = ((2.0, 0.0, 0.0), (5.0, 1.0, 48.0))
    roots, q = bent_knees(n, speed=5.0, mean=np.radians(60.0))
    out = arms_of(GaitAmplitude(replace(FEET["input"], knee_bend=run)), roots, q, q)
    flexion, own = np.degrees(knee_flexion(out)[settled]), np.degrees(knee_flexion(q)[settled])
    assert flexion.mean(axis=0) == pytest.approx([48.0, 48.0], abs=1.0)
    # the swing shrinks with it: by 0.8 but for what the low-pass lets into the level it
    # scales by (a triple pole of 15 frames passes part of a 1.5 Hz swing, out of phase)
    shrunk = np.ptp(flexion, axis=0) / np.ptp(own, axis=0)
    assert np.all((0.78 < shrunk) & (shrunk < 0.9)), shrunk
    assert knee_bend(None, world_positions(out[settled], roots[settled], SKELETON)) == pytest.approx(48.0, abs=1.0)
    # ...and tells them from the input's, bent 12 degrees more
    assert knee_bend(None, world_positions(q[settled], roots[settled], SKELETON)) == pytest.approx(60.0, abs=1.0)
    for joint in ("LeftLowerLeg", "RightLowerLeg"):
        assert np.abs(rot.log_map(out[:, HUMANOID_BONES.index(joint)])[:, 1:]).max() < 1e-9  # a hinge
    half = arms_of(GaitAmplitude(replace(FEET["input"], knee_bend=((2.0, 0.0, 0.0), (5.0, 0.5, 48.0)))), roots, q, q)
    assert np.degrees(knee_flexion(half)[settled]).mean() == pytest.approx(54.0, abs=1.0)
    still_roots, still = bent_knees(n, speed=0.0, mean=np.radians(60.0))
    assert arms_of(GaitAmplitude(replace(FEET["input"], knee_bend=run)), still_roots, still, still) is None


def test_forward_points_take_the_named_styles_share_of_their_own_place_at_the_source_paces():
    walk, run = (speed / 60 for speed in PACES["normal"])
    share = ARM_FORWARD_SHARE["active"]
    points = forward_points("normal", {"active": 1.0})
    # runs take none of active's place, so the run's point asks for no angle
    np.testing.assert_allclose(points, [[walk, share[0], ARM_FORWARDS["active"][0]], [run, share[1], 0.0]])
    assert forward_points("normal", {"active": 0.5, "masculine": 0.5})[0][1:] == pytest.approx(
        (share[0] / 2, ARM_FORWARDS["active"][0]))
    assert forward_points("normal", {"masculine": 1.0}) == ()  # a style not named keeps the restyle's
    assert amplitudes("normal", {"active": 1.0})["arm_forward"] == forward_points("normal", {"active": 1.0})


def test_elbow_forward_points_take_the_named_styles_share_of_their_own_angle_at_the_source_paces():
    walk, run = (speed / 60 for speed in PACES["normal"])
    share = ELBOW_FORWARD_SHARE["active"]
    points = elbow_forward_points("normal", {"active": 1.0})
    # runs take none of active's angle, so the run's point asks for none
    np.testing.assert_allclose(points, [[walk, share[0], ELBOW_FORWARDS["active"][0]], [run, share[1], 0.0]])
    assert elbow_forward_points("normal", {"active": 0.5, "masculine": 0.5})[0][1:] == pytest.approx(
        (share[0] / 2, ELBOW_FORWARDS["active"][0]))
    assert elbow_forward_points("normal", {"masculine": 1.0}) == ()  # a style not named keeps the restyle's
    assert amplitudes("normal", {"active": 1.0})["elbow_forward"] == points


def test_the_elbows_forward_angle_reads_where_the_upper_arm_points_and_its_turn_moves_it_exactly():
    from scipy.spatial.transform import Rotation

    from stylecast.motion.footlock.across import elbow_directions, elbow_forward_angle, elbow_forward_turns

    _, q = hanging(30, 0.0)
    directions = elbow_directions(q)
    for k, (j, out) in enumerate(zip(UPPER_ARM_INDEX, (1.0, -1.0))):
        elbow = Rotation.from_quat(q[:, j]).apply([out, 0.0, 0.0])  # the bone at rest points out to its side
        np.testing.assert_allclose(directions[:, k], elbow, atol=1e-12)
    angle = elbow_forward_angle(directions)
    np.testing.assert_allclose(angle, np.arctan2(directions[..., 2], -directions[..., 1]), atol=1e-12)
    aim = angle + np.linspace(-0.3, 0.3, 60).reshape(30, 2)
    for share in (1.0, 0.5):
        turned = q.copy()
        turned[:, UPPER_ARM_INDEX] = rot.multiply(elbow_forward_turns(directions, share * (aim - angle)),
                                                  q[:, UPPER_ARM_INDEX])
        np.testing.assert_allclose(elbow_forward_angle(elbow_directions(turned)), angle + share * (aim - angle),
                                   atol=1e-9)
    # an arm raised over level is left alone; one 62 degrees from straight down, in the fade,
    # is turned part of the way
    _, up = hanging(30, 0.0, out_deg=120.0)
    assert np.all(elbow_forward_turns(elbow_directions(up), aim - angle)[..., 3] == 1.0)
    _, fading = hanging(30, 0.0, out_deg=62.0)
    directions = elbow_directions(fading)
    turned = rot.log_map(elbow_forward_turns(directions, np.full((30, 2), 0.2)))
    assert np.all((np.linalg.norm(turned, axis=-1) > 0.01) & (np.linalg.norm(turned, axis=-1) < 0.19))


def test_a_walking_stream_carries_its_elbows_forward_as_the_style_and_a_standing_one_not_at_all():
    """Upper arms hanging and swinging forward and back while walking, the style asking for
    elbows 15 degrees forward at the walking pace: their mean moves there, their swing about
    it stays, the forearms and hands keep their own rotations; at half the share, half way;
    standing, left alone. The swing at 2 Hz in a 60 fps stream: a 1 Hz stride at the data's
    30, the rate the low-pass is chosen for."""
    from stylecast.motion.footlock.across import elbow_directions, elbow_forward_angle

    n, settled = 600, slice(240, None)
    walk = ((2.0, 1.0, 15.0), (5.0, 0.0, 0.0))
    roots, q = hanging(n, speed=2.0, hz=2.0, out_deg=25.0)

    def forward(rotations):
        return np.degrees(elbow_forward_angle(elbow_directions(rotations)))[settled]

    own = forward(q)
    out = arms_of(GaitAmplitude(replace(FEET["input"], elbow_forward=walk)), roots, q, q)
    assert np.abs(own.mean(axis=0) - 15.0).min() > 5.0  # an angle worth moving
    assert forward(out).mean(axis=0) == pytest.approx([15.0, 15.0], abs=1.0)
    assert np.ptp(forward(out), axis=0) == pytest.approx(np.ptp(own, axis=0), rel=0.05)  # the swing kept
    others = np.setdiff1d(np.arange(J), UPPER_ARM_INDEX)
    np.testing.assert_array_equal(out[:, others], q[:, others])
    half = arms_of(GaitAmplitude(replace(FEET["input"], elbow_forward=((2.0, 0.5, 15.0), (5.0, 0.0, 0.0)))),
                   roots, q, q)
    assert forward(half).mean(axis=0) == pytest.approx((own.mean(axis=0) + 15.0) / 2, abs=1.0)
    still_roots, still = hanging(n, speed=0.0, hz=2.0)
    assert arms_of(GaitAmplitude(replace(FEET["input"], elbow_forward=walk)), still_roots, still, still) is None


def leaning(q: np.ndarray, lean_deg: float, sway_deg: float = 2.0, hz: float = 1.0) -> np.ndarray:
    """A restyle of ``q`` that tilts the spine ``lean_deg`` to the right (about the hips'
    level forward axis) and sways it ``sway_deg`` side to side at ``hz`` (a stride's sway)."""
    from stylecast.motion.footlock.lean import leaned

    sway = np.radians(sway_deg) * np.sin(2 * np.pi * hz * np.arange(len(q)) / 60.0)
    return leaned(q, sway - np.radians(lean_deg))


def test_the_spine_lean_reads_the_line_to_the_head_and_its_turn_moves_it_exactly():
    """``spine_lean`` against forward kinematics by scipy's rotations (the hips' facing level,
    the angle towards its left), and ``leaned`` tilts it by exactly the angle asked, at any
    pose of the hips, turning the spine alone."""
    from scipy.spatial.transform import Rotation

    from stylecast.motion.footlock.lean import HIPS_INDEX, SPINE_INDEX, leaned, spine_lean

    rng = np.random.default_rng(3)
    q = rot.exp_map(rng.normal(0.0, 0.25, (50, J, 3)))
    q[:, HIPS_INDEX] = rot.exp_map(rng.normal(0.0, 1.0, (50, 3)) * [0.2, 3.0, 0.2])  # any facing, a little tilt
    world, head = Rotation.from_quat(q[:, HIPS_INDEX]) * Rotation.from_quat(q[:, SPINE_INDEX]), np.zeros((50, 3))
    for name in ("Chest", "UpperChest", "Neck", "Head"):
        j = HUMANOID_BONES.index(name)
        head += world.apply(np.array(SKELETON.offsets[j]))
        world = world * Rotation.from_quat(q[:, j])
    forward = Rotation.from_quat(q[:, HIPS_INDEX]).apply([0.0, 0.0, 1.0]) * [1.0, 0.0, 1.0]
    left = np.cross([0.0, 1.0, 0.0], forward / np.linalg.norm(forward, axis=1, keepdims=True))
    np.testing.assert_allclose(spine_lean(q, SKELETON.offsets), np.arctan2(np.sum(head * left, axis=1), head[:, 1]),
                               atol=1e-12)
    angle = rng.uniform(-0.2, 0.2, 50)
    out = leaned(q, angle)
    np.testing.assert_allclose(spine_lean(out, SKELETON.offsets), spine_lean(q, SKELETON.offsets) + angle, atol=1e-9)
    others = np.setdiff1d(np.arange(J), [SPINE_INDEX])
    np.testing.assert_array_equal(out[:, others], q[:, others])


def test_a_walking_stream_leans_as_the_performer_and_a_standing_one_not_at_all():
    """A restyle that leans a walk 4 degrees to the right and sways it: with the share 1 at the
    walking pace its mean lean goes to the performer's (within a tenth of a degree), its sway
    about it stays; at half the share, half way; standing, left alone."""
    from stylecast.motion.footlock.lean import spine_lean

    n, settled = 600, slice(240, None)
    roots, q = hanging(n, speed=2.0)
    out = leaning(q, 4.0)

    def lean(rotations):
        return np.degrees(spine_lean(rotations, SKELETON.offsets))[settled]

    walk = ((2.0, 1.0), (5.0, 1.0))
    own, restyled = lean(q), lean(out)
    assert own.mean() - restyled.mean() == pytest.approx(4.0, abs=0.01)  # a lean worth taking away
    leant = lean(arms_of(GaitAmplitude(replace(FEET["input"], performer_lean=walk)), roots, q, out))
    assert leant.mean() == pytest.approx(own.mean(), abs=0.1)
    assert np.ptp(leant - own) == pytest.approx(np.ptp(restyled - own), rel=0.05)  # the sway kept
    half = lean(arms_of(GaitAmplitude(replace(FEET["input"], performer_lean=((2.0, 0.5), (5.0, 0.5)))), roots, q, out))
    assert half.mean() == pytest.approx(own.mean() - 2.0, abs=0.1)
    still_roots, still = hanging(n, speed=0.0)
    assert arms_of(GaitAmplitude(replace(FEET["input"], performer_lean=walk)), still_roots, still,
                   leaning(still, 4.0)) is None


def test_a_walking_stream_carries_its_hands_forward_as_the_style_and_a_standing_one_not_at_all():
    """Hands swinging about 5 degrees forward of straight down while walking, the style asking
    for 25 at the walking pace: their mean moves there, their swing about it stays, how far
    they sit across does not change; at half the share, half way; standing, left alone."""
    from stylecast.motion.footlock.across import arm_places

    n, settled = 600, slice(240, None)
    walk = ((2.0, 1.0, 25.0), (5.0, 0.0, 0.0))
    roots, q = swinging(n, speed=2.0)

    def places(rotations):
        return arm_places(rotations, SKELETON.offsets)

    own = np.degrees(places(q).forward()[settled])
    out = arms_of(GaitAmplitude(replace(FEET["input"], arm_forward=walk)), roots, q, q)
    carried = np.degrees(places(out).forward()[settled])
    assert abs(own.mean() - 25.0) > 10.0  # a place worth moving
    assert carried.mean(axis=0) == pytest.approx([25.0, 25.0], abs=1.0)
    # the swing kept: over the quarter-second low-pass of the other parts (amplitude_tau) the
    # stride's own swing leaked into the mean and was carried against itself, 15 % wider
    assert np.ptp(carried, axis=0) == pytest.approx(np.ptp(own, axis=0), rel=0.05)
    np.testing.assert_allclose(places(out).across(), places(q).across(), atol=1e-9)  # a turn about "across"
    half = arms_of(GaitAmplitude(replace(FEET["input"], arm_forward=((2.0, 0.5, 25.0), (5.0, 0.0, 0.0)))), roots, q, q)
    assert np.degrees(places(half).forward()[settled]).mean() == pytest.approx((own.mean() + 25.0) / 2, abs=1.0)
    still_roots, still = swinging(n, speed=0.0)
    assert arms_of(GaitAmplitude(replace(FEET["input"], arm_forward=walk)), still_roots, still, still) is None


def test_still_points_take_the_named_styles_share_at_any_speed():
    share = STILL_ARM_SHARE["feminine"]
    assert still_points("normal", {"feminine": 1.0}) == ((0.0, share),)
    # the performer's own style (normal) is named by none: its share of a mix keeps the restyle's motion
    assert still_points("normal", {"feminine": 0.5, "normal": 0.5})[0][1] == pytest.approx(share / 2)
    assert still_points("normal", {"normal": 1.0}) == ()
    assert amplitudes("normal", {"feminine": 1.0})["still_arms"] == still_points("normal", {"feminine": 1.0})
    assert waving_points("normal", {"youthful": 1.0}) == ((0.0, WAVING_ARM_SHARE["youthful"]),)
    assert waving_points("normal", {"youthful": 0.5, "active": 0.5})[0][1] == pytest.approx(
        WAVING_ARM_SHARE["youthful"] / 2)
    assert waving_points("normal", {"active": 1.0}) == ()
    # a style read word by word leaves the arms to the performer, as every other amplitude
    assert still_points("auto", {"feminine": 1.0}) == waving_points("auto", {"youthful": 1.0}) == ()
    assert amplitudes("normal", {"youthful": 1.0})["waving_arms"] == waving_points("normal", {"youthful": 1.0})
    # the waving elbows: youthful's share, half in a half mix, none for a style not named or read word by word
    assert waving_elbow_points("normal", {"youthful": 1.0}) == ((0.0, WAVING_ELBOW_SHARE["youthful"]),)
    assert waving_elbow_points("normal", {"youthful": 0.5, "masculine": 0.5})[0][1] == pytest.approx(
        WAVING_ELBOW_SHARE["youthful"] / 2)
    assert waving_elbow_points("normal", {"masculine": 1.0}) == waving_elbow_points("auto", {"youthful": 1.0}) == ()
    assert amplitudes("normal", {"youthful": 1.0})["waving_elbows"] == waving_elbow_points("normal", {"youthful": 1.0})


def wobbled(q: np.ndarray, wobble_deg: float = 15.0, hz: float = 1.5, posture_deg: float = 20.0,
            axis=(1.0, 0.0, 0.0)) -> np.ndarray:
    """A restyle of ``q`` that holds each arm at another posture (upper arms ``posture_deg``
    about Z, elbows as many more about their rest axis) and wobbles the upper arms about
    ``axis`` by ``wobble_deg`` at ``hz``: the generator's own motion of an arm the performer
    holds (or, as an input, arms swinging)."""
    out = q.copy()
    wobble = np.radians(wobble_deg) * np.sin(2 * np.pi * hz * np.arange(len(q)) / 60.0)
    for upper, lower in zip(UPPER_ARM_INDEX, LOWER_ARM_INDEX):
        posture = rot.exp_map(np.array([0.0, 0.0, np.radians(posture_deg)]))
        out[:, upper] = rot.multiply(rot.multiply(rot.exp_map(np.outer(wobble, axis)), posture), q[:, upper])
        out[:, lower] = rot.multiply(rot.exp_map(np.array([0.0, np.radians(posture_deg * 1.25), 0.0])), q[:, lower])
    return out


def wobble_deg(arms: np.ndarray, inputs: np.ndarray, posture_deg: float = 20.0) -> np.ndarray:
    """(n, 2) each upper arm's angle (degrees) from ``wobbled``'s posture over the input's:
    the restyle's own motion about its posture, what the still and waving holds take away."""
    aim = rot.multiply(rot.exp_map(np.array([0.0, 0.0, np.radians(posture_deg)])), inputs[:, UPPER_ARM_INDEX])
    return np.degrees(np.linalg.norm(rot.log_map(rot.multiply(arms[:, UPPER_ARM_INDEX], rot.inverse(aim))), axis=-1))


def held_and_halved(field: str, roots, q, out, settled) -> tuple[np.ndarray, ContactSettings]:
    """The arms ``GaitAmplitude`` gives the restyle ``out`` (wobbled 15 degrees about the
    input ``q``) with the hold ``field`` (``still_arms``, ``waving_arms``) all on, checked to
    keep under 8 % of the wobble, and at half its share half of it; -> (the held arms, the
    settings with it all on)."""
    setting = replace(FEET["input"], **{field: ((0.0, 1.0),)})
    held = arms_of(GaitAmplitude(setting), roots, q, out)
    assert wobble_deg(out, q)[settled].max() == pytest.approx(15.0, abs=0.1)
    assert wobble_deg(held, q)[settled].max() < 0.08 * 15.0
    half = arms_of(GaitAmplitude(replace(FEET["input"], **{field: ((0.0, 0.5),)})), roots, q, out)
    assert wobble_deg(half, q)[settled].max() == pytest.approx(0.5 * 15.0, rel=0.1)
    return held, setting


def test_a_still_hanging_arm_moves_as_the_input_at_the_restyles_posture_and_a_swinging_one_is_left_alone():
    """The performer's arms held still, the restyle's at another posture and wobbling: held,
    each arm bone is the input's turned by the restyle's mean offset (the posture kept, the
    wobble 6 % of what it was, the low-pass's at 1.5 Hz); at half the share, half of the
    wobble; arms swinging as in a walk, and a stream's first frames, are left as restyled."""
    n, settled = 600, slice(240, None)
    roots, q = swinging(n, speed=0.0, amplitude_deg=0.3)
    out = wobbled(q)
    held, still = held_and_halved("still_arms", roots, q, out, settled)
    # the elbow's own posture kept (a steady offset), so a hinge stays a hinge
    elbow = lambda arms: rot.log_map(rot.multiply(arms[:, LOWER_ARM_INDEX], rot.inverse(q[:, LOWER_ARM_INDEX])))
    np.testing.assert_allclose(elbow(held)[settled], elbow(out)[settled], atol=1e-9)
    # the first frame counts as moving: the hold comes in over the low-passes, not at once
    assert wobble_deg(held, q)[:3].max() == pytest.approx(wobble_deg(out, q)[:3].max(), abs=0.01)
    walk_roots, walk = swinging(n, speed=2.0)
    walk = wobbled(walk, wobble_deg=25.0, hz=1.0, posture_deg=0.0, axis=(0.0, 1.0, 0.0))  # hands swinging 75-95 cm/s
    walk_out = wobbled(walk)
    np.testing.assert_allclose(arms_of(GaitAmplitude(still), walk_roots, walk, walk_out), walk_out, atol=1e-9)
    # a raised hand is a raise's or a wave's (the sways), not a hanging one
    wave_roots, wave = waving(n, sway_deg=0.0)
    wave_out = wobbled(wave)
    np.testing.assert_allclose(arms_of(GaitAmplitude(still), wave_roots, wave, wave_out), wave_out, atol=1e-9)


def test_a_waving_arm_moves_as_the_input_at_the_restyles_posture_and_a_raised_still_one_is_left_alone():
    """The performer waves both hands (20 degrees at 2 Hz), the restyle holds the arms at
    another posture and wobbles them (1.5 Hz): held, each arm bone is the input's turned by
    the restyle's mean offset (the performer's wave kept, the restyle's wobble 6 % of what it
    was, the low-pass's at 1.5 Hz); half the share, half; a raise (the hands held up still)
    and hanging arms are left as restyled."""
    n, settled = 600, slice(240, None)
    roots, q = waving(n, sway_deg=20.0, hz=2.0)
    out = wobbled(q)
    _, waves = held_and_halved("waving_arms", roots, q, out, settled)
    raise_roots, raised = waving(n, sway_deg=0.0)
    raised_out = wobbled(raised)
    np.testing.assert_allclose(arms_of(GaitAmplitude(waves), raise_roots, raised, raised_out), raised_out, atol=1e-9)
    hang_roots, hanging = swinging(n, speed=0.0, amplitude_deg=0.3)
    hanging_out = wobbled(hanging)
    np.testing.assert_allclose(arms_of(GaitAmplitude(waves), hang_roots, hanging, hanging_out), hanging_out,
                               atol=1e-9)


def test_a_waving_elbow_bends_the_share_of_the_way_to_the_performers_and_a_still_one_keeps_the_restyles():
    """The performer waves both hands (the elbows bending 0-85 degrees), the restyle bends
    them 25 degrees further and holds them there: with the waving hold on and all of the
    elbow given back, each held elbow bends as the performer's (the wave's own flexion kept);
    half given back, half of the restyle's extra bend left; the upper arms held at the
    restyle's posture either way; a still hanging arm's elbow keeps the restyle's bend
    whatever the share."""
    from stylecast.motion.hinges import add_elbow_flexion, elbow_flexion

    n, settled = 600, slice(240, None)
    roots, q = waving(n, sway_deg=30.0, hz=2.0)
    q = add_elbow_flexion(q, np.full((n, 2), np.radians(40.0)))  # the forearm's wave bends the elbow 0-85 degrees
    out = add_elbow_flexion(wobbled(q), np.full((n, 2), np.radians(25.0)))

    def held_with(elbow_share, roots=roots, q=q, out=out, field="waving_arms"):
        setting = replace(FEET["input"], **{field: ((0.0, 1.0),)}, waving_elbows=((0.0, elbow_share),))
        return arms_of(GaitAmplitude(setting), roots, q, out)

    kept, given, half = held_with(0.0), held_with(1.0), held_with(0.5)
    performers = np.maximum(elbow_flexion(q), 0.0)  # a hinge: never past straight, where the wave's swing takes it
    assert np.degrees(np.abs(elbow_flexion(kept) - performers)[settled]).min() > 10.0  # the restyle's bend, held
    np.testing.assert_allclose(elbow_flexion(given)[settled], performers[settled], atol=np.radians(0.5))
    bent = settled.start + np.flatnonzero(elbow_flexion(q)[settled].min(axis=1) > 0.0)  # the wave bends both
    np.testing.assert_allclose((elbow_flexion(half) - performers)[bent], 0.5 * (elbow_flexion(kept) - performers)[bent],
                               atol=np.radians(0.5))
    for arms in (given, half):  # the upper arms stay at the restyle's posture, their wobble held away
        assert wobble_deg(arms, q)[settled].max() < 0.08 * 15.0
    # a still hanging arm is held at the restyle's elbow: the share is a waving arm's alone
    hang_roots, hanging = swinging(n, speed=0.0, amplitude_deg=0.3)
    hanging_out = add_elbow_flexion(wobbled(hanging), np.full((n, 2), np.radians(25.0)))
    still, restyles = (held_with(share, hang_roots, hanging, hanging_out, field="still_arms") for share in (1.0, 0.0))
    np.testing.assert_allclose(elbow_flexion(still)[settled], elbow_flexion(restyles)[settled], atol=1e-9)
    assert wobble_deg(still, hanging)[settled].max() < 0.08 * 15.0  # held, so the share had its chance


def test_an_elbow_swings_by_the_gain_and_stays_a_hinge():
    """An elbow (``motion.hinges``: it flexes about its Y) bending back and forth while
    walking: its flexion's swing is scaled by the gain about its mean, it bends sideways no
    more than before (a hinge), and a gain that would take it past straight stops it there. Scaled as a free rotation, the elbows went off their hinge."""
    from stylecast.motion.hinges import elbow_flexion

    n, settled = 600, slice(180, None)
    roots, q = swinging(n, speed=2.0, amplitude_deg=0.0)
    left = HUMANOID_BONES.index("LeftLowerArm")
    bend = 0.6 + 0.3 * np.sin(2 * np.pi * np.arange(n) / 60.0)  # radians, 1 Hz
    q[:, left] = rot.exp_map(np.outer(-bend, [0.0, 1.0, 0.0]))  # the left elbow bends with -Y (``HINGES``)
    assert elbow_flexion(q)[settled, 0] == pytest.approx(bend[settled])  # the instrument reads the bend
    out = arms_of(GaitAmplitude(replace(FEET["input"], arm_swing=((2.0, 0.5),))), roots, q, q)
    flexion = elbow_flexion(out)[settled, 0]
    assert np.ptp(flexion) / np.ptp(bend[settled]) == pytest.approx(0.5, abs=0.08)
    assert flexion.mean() == pytest.approx(bend[settled].mean(), abs=0.02)
    sideways = rot.log_map(out[:, left])[:, [0, 2]]
    assert np.abs(sideways).max() < 1e-9  # a hinge still
    # an elbow nearly straight at the end of its swing, its swing grown by half: it would pass
    # straight, and stops there instead
    near = 0.3 + 0.28 * np.sin(2 * np.pi * np.arange(n) / 60.0)
    q[:, left] = rot.exp_map(np.outer(-near, [0.0, 1.0, 0.0]))
    wide = elbow_flexion(arms_of(GaitAmplitude(replace(FEET["input"], arm_swing=((2.0, 1.5),))), roots, q, q))[:, 0]
    assert wide.min() >= -1e-12 and np.count_nonzero(wide[settled] <= 1e-9) > 10


def test_the_restyles_own_change_of_the_arms_is_kept():
    """The swing adds (g - 1) of the INPUT's swing to the restyled arm: a restyle that turns the
    arm by a fixed rotation keeps that turn, and where the input holds its arm still, the
    restyled arm's own motion passes untouched."""
    settings = replace(FEET["input"], arm_swing=((2.0, 0.5),))
    roots, q = swinging(400, speed=2.0)
    turn = rot.exp_map(np.array([0.0, 0.0, 0.4]))
    restyled = q.copy()
    restyled[:, SWING_INDEX] = rot.multiply(turn, q[:, SWING_INDEX])
    out = arms_of(GaitAmplitude(settings), roots, q, restyled)
    plain = arms_of(GaitAmplitude(settings), roots, q, q)
    # out = S q and restyled-then-swung = S turn q: the same swing S on top of the turn
    s_plain = rot.multiply(plain[:, SWING_INDEX], rot.inverse(q[:, SWING_INDEX]))
    s_turned = rot.multiply(out[:, SWING_INDEX], rot.inverse(restyled[:, SWING_INDEX]))
    np.testing.assert_allclose(np.abs(np.sum(s_plain * s_turned, axis=-1)), 1.0, atol=1e-12)
    _, held = swinging(400, speed=2.0, amplitude_deg=0.0)  # the input's arms still
    _, moving = swinging(400, speed=2.0)
    kept = arms_of(GaitAmplitude(settings), roots, held, moving)
    np.testing.assert_allclose(kept[:, SWING_INDEX], moving[:, SWING_INDEX], atol=1e-12)


def bobbing(n: int, speed: float, amplitude: float = 2.0, hz: float = 2.0) -> np.ndarray:
    """Roots moving ``speed`` cm a frame along +Z, their height rising and falling by
    ``amplitude`` cm at ``hz`` (a step each half stride)."""
    t = np.arange(n) / 60.0
    return np.stack([np.zeros(n), 100.0 + amplitude * np.sin(2 * np.pi * hz * t), speed * np.arange(n)], axis=1)


def test_a_walking_stream_bobs_its_hips_by_the_gain_and_a_standing_one_not_at_all():
    settings = replace(FEET["input"], hips_bob=((2.0, 0.5), (5.0, 2.0)))
    _, q = swinging(600, speed=0.0)
    settled = slice(180, None)

    def bob(heights):
        return (heights[settled].max() - heights[settled].min()) / 2

    roots = bobbing(600, speed=2.0)
    assert bob(roots[:, 1]) == pytest.approx(2.0, abs=0.02)  # the instrument sees the input's bob (sampled peaks)
    swung, bobbed = GaitAmplitude(settings).apply(roots, q, q, roots[:, 1])
    assert swung is None  # no arm swing set: the arms as they were
    # half the bob at the walking gain, about its low-passed level (which keeps a little of
    # a 2 Hz bob, so the bob about it is a little less than the whole)
    assert bob(bobbed) == pytest.approx(1.0, abs=0.1)
    # at a run the points ask for twice the bob: a bob only lessens, the hips are left as they are
    assert GaitAmplitude(settings).apply(bobbing(600, speed=5.0), q, q, roots[:, 1]) == (None, None)
    _, between = GaitAmplitude(settings).apply(bobbing(600, speed=2.5), q, q, roots[:, 1])
    assert bob(between) == pytest.approx(2.0 * 0.75, abs=0.15)  # the line through the points
    # the level the hips bob about stays where it was: the mean height is the input's
    assert bobbed[settled].mean() == pytest.approx(roots[settled, 1].mean(), abs=0.05)
    still = bobbing(600, speed=0.0)  # standing (a squat, a bounce): left alone
    assert GaitAmplitude(settings).apply(still, q, q, still[:, 1]) == (None, None)


def test_the_hips_bob_reads_a_known_rise_and_fall():
    """``metrics.hips_bob`` (the table's instrument): hips rising and falling 2 cm at 2 Hz
    read 2 / sqrt(2) cm, hips that only glide read none, and a slow drift of the height
    (a ramp) is not a bob."""
    n = 600
    positions = np.zeros((n, J, 3))
    positions[:, 0] = bobbing(n, speed=2.0)
    assert hips_bob(positions) == pytest.approx(2.0 / np.sqrt(2.0), rel=0.02)
    positions[:, 0, 1] = 100.0
    assert hips_bob(positions) == 0.0
    positions[:, 0, 1] = 100.0 + 0.05 * np.arange(n)  # 3 cm a second, slowly
    assert hips_bob(positions) < 1e-9


def test_a_clip_at_once_is_each_stream_a_frame_at_a_time():
    """``apply`` on a whole clip equals ``amplitude_frames`` over several streams, one frame
    each per call (the daemon's tick), with different amplitudes and a fade."""
    n = 240
    streams = [(bobbing(n, speed), swinging(n, speed, seed=k)[1]) for k, speed in enumerate((2.0, 5.0, 0.0, 2.0))]
    streams.append(waving(n))  # a standing wave, its raised hands' sway scaled
    streams.append(swinging(n, 0.0, amplitude_deg=0.3, seed=5))  # arms held still, restyled to wobble
    streams.append(waving(n, hz=1.0, seed=6))  # a wave, restyled to wobble
    restyled = [q for _, q in streams[:-2]] + [wobbled(q) for _, q in streams[-2:]]
    settings = [replace(FEET["input"], arm_swing=arms, hips_bob=hips, arm_across=across, wave_sway=wave,
                        raise_sway=lift, elbow_bend=bend, arm_forward=forward)
                for arms, hips, across, wave, lift, bend, forward in
                ((((2.0, 0.5), (5.0, 2.0)), ((2.0, 0.5),), ((2.0, 0.0),), (), (), ((1.0, 0.0, 0.0), (5.0, 1.0, 60.0)),
                  ((2.0, 0.5, 20.0), (5.0, 0.0, 0.0))),
                 (((2.0, 1.5),), (), ((5.0, 0.5),), ((0.0, 1.5), (2.0, 1.0)), (), ((2.0, 0.5, 30.0),),
                  ((2.0, 1.0, -5.0),)),
                 (((2.0, 0.5),), ((2.0, 2.0),), ((2.0, 0.3), (5.0, 0.8)), (), (), (), ()), ((), (), (), (), (), (), ()),
                 ((), (), ((2.0, 0.0),), ((0.0, 1.6), (2.0, 1.0)), ((0.0, 0.5), (2.0, 1.0)), (), ()))]
    settings.append(replace(FEET["input"], still_arms=((0.0, 1.0),), arm_forward=((2.0, 0.5, 20.0),)))
    settings.append(replace(FEET["input"], still_arms=((0.0, 1.0),), waving_arms=((0.0, 1.0),),
                            waving_elbows=((0.0, 0.5),)))
    settings[1] = replace(settings[1], knee_bend=((2.0, 1.0, 25.0), (5.0, 0.5, 40.0)))
    settings[0] = replace(settings[0], elbow_forward=((2.0, 1.0, 15.0), (5.0, 0.5, 5.0)))
    settings[1] = replace(settings[1], performer_lean=((2.0, 1.0), (5.0, 0.5)))
    restyled[1] = leaning(restyled[1], 3.0)
    mixes = [np.ones(n), np.clip(np.arange(n) / 60.0, 0.0, 1.0), np.ones(n), np.ones(n),
             np.clip(np.arange(n) / 90.0, 0, 1), np.clip(np.arange(n) / 30.0, 0.0, 1.0),
             np.clip(np.arange(n) / 45.0, 0.0, 1.0)]
    whole = []
    for setting, (r, q), out, m in zip(settings, streams, restyled, mixes):
        swung, bobbed = GaitAmplitude(setting).apply(r, q, out, r[:, 1], m, SKELETON.offsets)
        whole.append((out if swung is None else swung, r[:, 1] if bobbed is None else bobbed))
    live = [GaitAmplitude(s) for s in settings]
    for t in range(n):
        inputs = np.stack([q[t] for _, q in streams])
        outputs, heights = np.stack([out[t] for out in restyled]), np.array([r[t, 1] for r, _ in streams])
        amplitude_frames(live, np.stack([r[t] for r, _ in streams]), inputs, outputs, heights, [m[t] for m in mixes],
                         SKELETON.offsets)
        for k in range(len(streams)):
            np.testing.assert_allclose(outputs[k], whole[k][0][t], atol=1e-12)
            assert heights[k] == pytest.approx(whole[k][1][t], abs=1e-9)
    assert np.abs(whole[0][0] - streams[0][1]).max() > 0.01 and np.abs(whole[0][1] - streams[0][0][:, 1]).max() > 0.1
    assert live[0]._moving[2] and live[1]._moving[2]  # the swing across was exercised (the third stands)
    assert live[4]._moving[3:5] == [True, True] and np.abs(whole[4][0] - streams[4][1]).max() > 0.01  # and the sways
    assert live[0]._moving[5:7] == [True, True] and live[1]._moving[5:7] == [True, True]  # and the elbows' bend
    assert live[0]._moving[7:9] == [True, True] and live[1]._moving[7:9] == [True, True]  # and the hands carried
    assert live[5]._moving[9] and np.abs(whole[5][0] - restyled[5]).max() > 0.01  # and the still arms held
    assert live[6]._moving[10:12] == [True, True] and np.abs(whole[6][0] - restyled[6]).max() > 0.01  # and the
    # waving arms held, their elbows half given back
    assert live[1]._moving[12:14] == [True, True] and not live[0]._moving[12]  # and the knees' bend
    assert live[0]._moving[14:16] == [True, True] and not live[1]._moving[14]  # and the elbows carried
    assert live[1]._moving[16] and not live[0]._moving[16]  # and the lean


def test_a_live_change_of_style_moves_the_arms_smoothly():
    """A new swing set mid-stream (``set_points``: /stylecast/style) eases in over the
    low-pass: no frame turns the arm by more than the input's own swing does."""
    roots, q = swinging(600, speed=2.0)
    amplitude = GaitAmplitude(replace(FEET["input"], arm_swing=((2.0, 1.0),)))
    first = arms_of(amplitude, roots[:300], q[:300], q[:300])
    amplitude.set_points(arm_swing=((2.0, 0.4),))
    second = arms_of(amplitude, roots[300:], q[300:], q[300:])
    out = np.concatenate([q[:300] if first is None else first, second])
    step = np.degrees(np.linalg.norm(rot.log_map(rot.multiply(out[1:, UPPER_ARM], rot.inverse(out[:-1, UPPER_ARM]))),
                                     axis=-1))
    own = np.degrees(np.linalg.norm(rot.log_map(rot.multiply(q[1:, UPPER_ARM], rot.inverse(q[:-1, UPPER_ARM]))),
                                    axis=-1))
    assert step.max() <= own.max() + 1e-9
    # and the swing reaches the new gain
    assert swing_deg(out, slice(480, None)) < 0.5 * swing_deg(q, slice(480, None))


def test_a_teleport_of_the_root_is_not_a_sprint():
    """A looped clip jumping back (``TELEPORT_STEP``) keeps the last speed: the gain does
    not leap to the runs' for one jump."""
    settings = replace(FEET["input"], arm_swing=((2.0, 1.0), (5.0, 3.0)))
    roots, q = swinging(400, speed=2.0)
    roots[200:, 2] -= 600.0  # the clip starts over
    out = arms_of(GaitAmplitude(settings), roots, q, q)
    # gain 1 at the walk (within the low-pass's rounding), and the jump did not move it
    np.testing.assert_allclose(q if out is None else out, q, atol=1e-9)
    runs = GaitAmplitude(replace(settings, arm_swing=((2.0, 1.0), (3.0, 3.0))))  # the control: a faster
    roots[200:, 2] += 600.0 - 10.0  # ...step of 8 cm a frame, not a jump, does move the arms
    assert np.abs(arms_of(runs, roots, q, q) - q).max() > 0.01


@needs_data
def test_a_held_out_walk_swings_its_arms_and_bobs_as_the_style_and_a_wave_is_left_alone():
    """Real takes through the foot lock with the pose unchanged (the amplitudes alone): a
    held-out normal walk given the elderly amplitudes swings its hands and bobs its hips by
    about the table's ratios (the walks' 0.51 and 0.54), a held-out wave keeps its hands as
    they were."""
    from stylecast.models.data import bandai_skeleton

    files = D.list_files(DATA)
    sk = bandai_skeleton(files)
    settings = replace(FEET["input"], **amplitudes("normal", {"elderly": 1.0}))
    for action, low, high in (("walk", 0.40, 0.62), ("wave-left-hand", 0.98, 1.02)):
        take = next(f for f in D.files_for_style(files, "normal", "val") if f.action == action)
        m = D.load_motions([take])[0]
        roots, q = m.root_positions.astype(np.float64), m.rotations.astype(np.float64)
        lock = FootLock(sk, settings=settings)
        lock.push(roots, q)
        new_roots, out = lock.apply(0, roots, q, q)
        p_in, p_out = world_positions(q, roots, sk), world_positions(out, new_roots, sk)
        before, after = arm_swing(hips_yaw(q), p_in), arm_swing(hips_yaw(out), p_out)
        assert low <= after / before <= high, (action, after / before)
        if action == "walk":  # the hips bob about the elderly walks' 0.54 of it
            assert 0.4 <= hips_bob(p_out) / hips_bob(p_in) <= 0.7, hips_bob(p_out) / hips_bob(p_in)
