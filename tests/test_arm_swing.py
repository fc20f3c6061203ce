"""The style's arm swing (models/arm_swing.py, motion/footlock/ ``ArmSwing``): the table is
what the training clips measure, a walking stream's arms swing by the style's ratio while
a standing one's (a wave) are left alone, the restyle's own change of the arms is kept, a
clip at once equals a stream a frame at a time, and a live change of style never steps
the arms."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stylecast.models import data as D
from stylecast.models.arm_swing import ARM_SWINGS, arm_swing_points, measure_arm_swings
from stylecast.models.metrics import arm_swing, hips_yaw, world_positions
from stylecast.models.pace import PACES
from stylecast.motion import rotations as rot
from stylecast.motion.footlock import FEET, ArmSwing, FootLock
from stylecast.motion.footlock.arms import SWING_INDEX, swing_frames
from stylecast.motion.humanoid import HUMANOID_BONES

DATA = D.default_data_dir()
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason=f"the shared Bandai data is not at {DATA}")
J = len(HUMANOID_BONES)
UPPER_ARM = HUMANOID_BONES.index("LeftUpperArm")


@needs_data
def test_the_arm_swing_table_is_what_the_training_clips_measure():
    measured = measure_arm_swings(D.list_files(DATA))
    assert set(measured) == set(ARM_SWINGS)
    for style, (walks, runs) in measured.items():
        assert ARM_SWINGS[style] == pytest.approx((walks, runs), abs=0.0051), style


def test_arm_swing_points_give_the_target_mix_over_the_source_at_the_source_paces():
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


def test_the_gain_is_one_at_rest_and_the_line_through_its_points():
    swing = ArmSwing(replace(FEET["input"], arm_swing=((2.0, 0.5), (5.0, 2.0))))
    assert swing.gain(0.0) == 1.0
    assert swing.gain(1.0) == pytest.approx(0.75)
    assert swing.gain(3.5) == pytest.approx(1.25)
    assert swing.gain(9.0) == pytest.approx(2.0)
    assert ArmSwing(FEET["input"]).gain(3.0) == 1.0  # no points: the input's swing


def swinging(n: int, speed: float, amplitude_deg: float = 20.0, hz: float = 1.0, seed: int = 0):
    """A synthetic stream: roots moving ``speed`` cm a frame along +Z, every bone turned a
    little from the rest pose (random, fixed), the arms swinging about X at ``hz``."""
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
    settings = replace(FEET["input"], arm_swing=((2.0, 0.5), (5.0, 2.0)))
    settled = slice(180, None)
    roots, q = swinging(600, speed=2.0)
    out = ArmSwing(settings).apply(roots, q, q)
    # the instrument sees the swing as it is where nothing is done...
    assert swing_deg(q, settled) == pytest.approx(20.0, abs=0.1)
    # ...half of it at the walking gain (the low-passed mean keeps ~15 % of a 1 Hz swing, so
    # the swing about the input's mean is a little less than the input's whole swing)
    assert swing_deg(out, settled) == pytest.approx(10.0, abs=1.6)
    fast_roots, _ = swinging(600, speed=5.0)
    faster = ArmSwing(settings).apply(fast_roots, q, q)
    assert swing_deg(faster, settled) == pytest.approx(40.0, abs=3.2)
    # the other bones are the restyle's, untouched
    others = np.setdiff1d(np.arange(J), SWING_INDEX)
    np.testing.assert_array_equal(out[:, others], q[:, others])
    # standing (the roots still: a wave, a raise): the arms are the action, left as they are
    still = np.repeat(roots[:1], len(roots), axis=0)
    assert ArmSwing(settings).apply(still, q, q) is None
    # no swing set: nothing changes either
    assert ArmSwing(FEET["input"]).apply(roots, q, q) is None


def test_the_restyles_own_change_of_the_arms_is_kept():
    """The swing adds (g - 1) of the INPUT's swing to the restyled arm: a restyle that turns the
    arm by a fixed rotation keeps that turn, and where the input holds its arm still, the
    restyled arm's own motion passes untouched."""
    settings = replace(FEET["input"], arm_swing=((2.0, 0.5),))
    roots, q = swinging(400, speed=2.0)
    turn = rot.exp_map(np.array([0.0, 0.0, 0.4]))
    restyled = q.copy()
    restyled[:, SWING_INDEX] = rot.multiply(turn, q[:, SWING_INDEX])
    out = ArmSwing(settings).apply(roots, q, restyled)
    plain = ArmSwing(settings).apply(roots, q, q)
    # out = S q and restyled-then-swung = S turn q: the same swing S on top of the turn
    s_plain = rot.multiply(plain[:, SWING_INDEX], rot.inverse(q[:, SWING_INDEX]))
    s_turned = rot.multiply(out[:, SWING_INDEX], rot.inverse(restyled[:, SWING_INDEX]))
    np.testing.assert_allclose(np.abs(np.sum(s_plain * s_turned, axis=-1)), 1.0, atol=1e-12)
    _, held = swinging(400, speed=2.0, amplitude_deg=0.0)  # the input's arms still
    _, moving = swinging(400, speed=2.0)
    kept = ArmSwing(settings).apply(roots, held, moving)
    np.testing.assert_allclose(kept[:, SWING_INDEX], moving[:, SWING_INDEX], atol=1e-12)


def test_a_clip_at_once_is_each_stream_a_frame_at_a_time():
    """``apply`` on a whole clip equals ``swing_frames`` over several streams, one frame each
    per call (the daemon's tick), with different swings and a fade."""
    n = 240
    streams = [swinging(n, speed, seed=k) for k, speed in enumerate((2.0, 5.0, 0.0))]
    settings = [replace(FEET["input"], arm_swing=points) for points in
                (((2.0, 0.5), (5.0, 2.0)), ((2.0, 1.5),), ((2.0, 0.5),))]
    mixes = [np.ones(n), np.clip(np.arange(n) / 60.0, 0.0, 1.0), np.ones(n)]
    whole = [ArmSwing(s).apply(r, q, q, m) for s, (r, q), m in zip(settings, streams, mixes)]
    whole = [q if w is None else w for w, (_, q) in zip(whole, streams)]
    live = [ArmSwing(s) for s in settings]
    frames = np.stack([q for _, q in streams], axis=1).copy()  # (n, streams, J, 4)
    for t in range(n):
        outputs = frames[t].copy()
        swing_frames(live, np.stack([r[t] for r, _ in streams]), frames[t], outputs, [m[t] for m in mixes])
        for k in range(len(streams)):
            np.testing.assert_allclose(outputs[k], whole[k][t], atol=1e-12)


def test_a_live_change_of_style_moves_the_arms_smoothly():
    """A new swing set mid-stream (``set_points``: /stylecast/style) eases in over the
    low-pass: no frame turns the arm by more than the input's own swing does."""
    roots, q = swinging(600, speed=2.0)
    swing = ArmSwing(replace(FEET["input"], arm_swing=((2.0, 1.0),)))
    first = swing.apply(roots[:300], q[:300], q[:300])
    swing.set_points(((2.0, 0.4),))
    second = swing.apply(roots[300:], q[300:], q[300:])
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
    out = ArmSwing(settings).apply(roots, q, q)
    # gain 1 at the walk (within the low-pass's rounding), and the jump did not move it
    np.testing.assert_allclose(q if out is None else out, q, atol=1e-9)
    runs = ArmSwing(replace(settings, arm_swing=((2.0, 1.0), (3.0, 3.0))))  # the control: a faster
    roots[200:, 2] += 600.0 - 10.0  # ...step of 8 cm a frame, not a jump, does move the arms
    assert np.abs(runs.apply(roots, q, q) - q).max() > 0.01


@needs_data
def test_a_held_out_walk_swings_its_arms_as_the_style_and_a_wave_is_left_alone():
    """Real takes through the foot lock with the pose unchanged (the swing alone): a
    held-out normal walk given the elderly swing swings its hands by about the table's
    ratio (the walks' 0.51), a held-out wave keeps its hands as they were."""
    from stylecast.models.data import bandai_skeleton

    files = D.list_files(DATA)
    sk = bandai_skeleton(files)
    settings = replace(FEET["input"], arm_swing=arm_swing_points("normal", {"elderly": 1.0}))
    for action, low, high in (("walk", 0.40, 0.62), ("wave-left-hand", 0.98, 1.02)):
        take = next(f for f in D.files_for_style(files, "normal", "val") if f.action == action)
        m = D.load_motions([take])[0]
        roots, q = m.root_positions.astype(np.float64), m.rotations.astype(np.float64)
        lock = FootLock(sk, settings=settings)
        lock.push(roots, q)
        new_roots, out = lock.apply(0, roots, q, q)
        before = arm_swing(hips_yaw(q), world_positions(q, roots, sk))
        after = arm_swing(hips_yaw(out), world_positions(out, new_roots, sk))
        assert low <= after / before <= high, (action, after / before)
