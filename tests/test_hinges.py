"""Elbows and knees stay hinges (motion/hinges.py): on real Bandai motion, on known-bad
restyles, and through the stream code `restyle` and `serve` share."""

from __future__ import annotations

import numpy as np
import pytest

from stylecast.motion import rotations as rot
from stylecast.motion.bvh import read_bvh
from stylecast.motion import hinges
from stylecast.motion.hinges import EASE_BAND, EASE_SHARE, HINGES, _swing_twist, eased_bend, keep_hinges
from stylecast.motion.humanoid import HUMANOID_BONES, Retarget
from stylecast.motion.resample import resample

HINGE_BONES = {h.bone for h in HINGES}


@pytest.fixture(scope="module")
def walk(bandai_root) -> np.ndarray:
    """A held-out normal walk as humanoid rotations at 60 fps."""
    clip = read_bvh(bandai_root / "dataset-2" / "data" / "dataset-2_walk_normal_001.bvh.gz")
    return resample(Retarget.for_clip(clip).to_humanoid(clip), 60.0).rotations.astype(np.float64)


def parts(q: np.ndarray, hinge) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(flexion, sideways bend, twist) of a hinge bone's rotations (T, 4), in degrees."""
    swing, twist = _swing_twist(q, hinge.axis)
    side = 3 - hinge.axis - hinge.flexion
    angle = np.degrees(2 * np.arctan2(twist[:, hinge.axis], twist[:, 3]))
    return np.degrees(swing[:, hinge.flexion]), np.degrees(swing[:, side]), (angle + 180.0) % 360.0 - 180.0


def turned(q: np.ndarray, bone: str, axis: int, degrees: float) -> np.ndarray:
    """``q`` with one bone turned by ``degrees`` about a local axis, on top of its rotation."""
    out = q.copy()
    j = HUMANOID_BONES.index(bone)
    v = np.zeros(3)
    v[axis] = np.radians(degrees)
    out[:, j] = rot.multiply(rot.exp_map(np.broadcast_to(v, out[:, j, :3].shape)), out[:, j])
    return out


def test_the_data_s_elbows_and_knees_are_hinges(walk):
    for hinge in HINGES:
        flexion, side, twist = parts(walk[:, HUMANOID_BONES.index(hinge.bone)], hinge)
        assert np.abs(side).max() < 0.5, hinge.bone
        assert np.all(hinge.bent * flexion > -0.5), hinge.bone  # never past straight
        if not hinge.twists:
            assert np.abs(twist).max() < 1.0, hinge.bone


def test_real_motion_passes_unchanged(walk):
    assert rot.angle_between(keep_hinges(walk, walk), walk).max() < 1e-9


def test_a_sideways_bend_and_a_knee_twist_are_taken_out_and_the_flexion_kept(walk):
    bad = turned(walk, "LeftLowerArm", 2, 10.0)  # elbow bent sideways
    bad = turned(bad, "RightLowerLeg", 1, 8.0)  # knee twisted
    bad = turned(bad, "RightLowerLeg", 2, -6.0)  # ... and bent sideways
    bad = turned(bad, "RightLowerArm", 1, 12.0)  # more elbow flexion: allowed
    fixed = keep_hinges(walk, bad)
    for hinge in HINGES:
        j = HUMANOID_BONES.index(hinge.bone)
        flex_in, side_in, twist_in = parts(walk[:, j], hinge)
        flex_bad, _, twist_bad = parts(bad[:, j], hinge)
        flex, side, twist = parts(fixed[:, j], hinge)
        np.testing.assert_allclose(side, side_in, atol=1e-6, err_msg=hinge.bone)
        np.testing.assert_allclose(twist, twist_bad if hinge.twists else twist_in, atol=1e-6, err_msg=hinge.bone)
        bent = hinge.bent * flex_bad > 0
        np.testing.assert_allclose(flex[bent], flex_bad[bent], atol=1e-6, err_msg=hinge.bone)
    right_elbow = HUMANOID_BONES.index("RightLowerArm")
    assert rot.angle_between(fixed[:, right_elbow], bad[:, right_elbow]).max() < 0.01  # a flexion of 12 degrees stays
    others = [j for j, b in enumerate(HUMANOID_BONES) if b not in HINGE_BONES]
    assert np.array_equal(fixed[:, others], bad[:, others])


def test_a_joint_bent_past_straight_stops_at_straight_or_at_the_input(walk):
    hinge = next(h for h in HINGES if h.bone == "LeftLowerLeg")
    j = HUMANOID_BONES.index(hinge.bone)
    straight = walk.copy()
    straight[:, j] = rot.identity((len(walk),))
    past = turned(straight, hinge.bone, hinge.flexion, -hinge.bent * 7.0)
    flexion, _, _ = parts(keep_hinges(straight, past)[:, j], hinge)
    assert np.abs(flexion).max() < 1e-9
    # An input already past straight by 3 degrees: the restyle may not take it further.
    over = turned(straight, hinge.bone, hinge.flexion, -hinge.bent * 3.0)
    flexion, _, _ = parts(keep_hinges(over, past)[:, j], hinge)
    np.testing.assert_allclose(flexion, -hinge.bent * 3.0, atol=1e-6)


def hard_stop(bend_in, bend_out):
    """The previous release's rule, a known-bad case: the restyle's flexion, cut at straight."""
    return np.maximum(bend_out, np.minimum(bend_in, 0.0))


def test_a_flexion_straightened_past_its_input_eases_to_straight_with_a_continuous_slope():
    bend_in = np.radians(10.0)
    wanted = np.linspace(np.radians(-20.0), np.radians(20.0), 40001)  # what the restyle asks for
    for rule, continuous in ((eased_bend, True), (hard_stop, False)):
        kept = rule(np.full_like(wanted, bend_in), wanted)
        assert kept.min() >= 0.0  # never past straight: the input is not
        slope = np.diff(kept) / np.diff(wanted)
        assert (np.abs(np.diff(slope)).max() < 1e-3) == continuous, rule.__name__  # a corner: the slope jumps by 1
    kept = eased_bend(np.full_like(wanted, bend_in), wanted)
    exact = wanted >= min(EASE_SHARE * bend_in, EASE_BAND)  # far enough from straight
    np.testing.assert_array_equal(kept[exact], wanted[exact])
    assert np.all(kept[~exact] > wanted[~exact])
    # Far from straight a restyle straightens a joint as much as it likes (an elbow 104 -> 14 degrees).
    np.testing.assert_array_equal(eased_bend(np.radians([104.0]), np.radians([14.0])), np.radians([14.0]))
    # The input's own flexion comes back unchanged, straight and past straight included.
    own = np.radians(np.array([-3.0, 0.0, 0.5, 10.0, 90.0]))
    np.testing.assert_array_equal(eased_bend(own, own), own)
    # Past straight in the input: the restyle may not take it further, and may bend it.
    np.testing.assert_array_equal(eased_bend(own[:1], own[:1] - 0.1), own[:1])
    np.testing.assert_array_equal(eased_bend(own[:1], own[:1] + 0.1), own[:1] + 0.1)


def test_a_knee_restyled_straighter_than_its_input_turns_at_straight_without_a_corner():
    """A knee that extends to straight at 1.5 degrees a frame and bends again (a heel strike),
    restyled 5 degrees straighter: the hard stop stopped it dead from 1 degree a frame and
    held it straight; eased, its speed changes by under 0.4 degrees a frame from one frame
    to the next."""
    hinge = next(h for h in HINGES if h.bone == "LeftLowerLeg")
    j = HUMANOID_BONES.index(hinge.bone)
    flexion = np.abs(np.arange(-20, 21)) * 1.5  # degrees: straight at frame 20 alone
    bent = np.zeros((len(flexion), len(HUMANOID_BONES), 3))
    bent[:, j, hinge.flexion] = np.radians(hinge.bent * flexion)
    inputs = rot.exp_map(bent)
    restyled = turned(inputs, hinge.bone, hinge.flexion, -hinge.bent * 5.0)
    corners = {}
    for rule in (eased_bend, hard_stop):
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(hinges, "eased_bend", rule)
            kept = hinge.bent * parts(keep_hinges(inputs, restyled)[:, j], hinge)[0]
        assert kept.min() > -1e-9  # never past straight
        np.testing.assert_allclose(kept[:12], flexion[:12] - 5.0, atol=1e-6)  # far from straight: the restyle's
        corners[rule] = np.abs(np.diff(kept, 2)).max()
    assert corners[eased_bend] < 0.4
    assert corners[hard_stop] > 0.9


def test_a_restyle_that_straightens_an_arm_does_not_pop_it(bandai_root):
    """The multistyle model made youthful, a held-out right-hand raise through the stream with
    its foot lock: the raised arm's elbow straightened past the input's and held straight
    popped the hand at 2.6x the input's largest one-frame jerk; eased, it stays within 1.5x."""
    from stylecast.models import metrics as M
    from stylecast.models.restyle import restyle_rotations
    from stylecast.models.restyler import Restyler
    from stylecast.motion.footlock import AUTO_FEET, feet_for
    from stylecast.motion.words import stream_settings_of

    clip = read_bvh(bandai_root / "dataset-2" / "data" / "dataset-2_raise-up-right-hand_normal_023.bvh.gz")
    humanoid = resample(Retarget.for_clip(clip).to_humanoid(clip), 60.0)
    inp, roots = humanoid.rotations.astype(np.float64), humanoid.root_positions.astype(np.float64)
    r = Restyler.load("multistyle").with_performer_style("normal").for_target("youthful")
    jerk_in = M.jerk(M.world_positions(inp, roots, humanoid.skeleton))

    def pops():
        out, moved = restyle_rotations(inp, r.restyle_words, contacts=feet_for(AUTO_FEET, r), roots=roots,
                                       skeleton=humanoid.skeleton, **stream_settings_of(r))
        return M.peak_jerk_ratio(jerk_in, M.jerk(M.world_positions(out, moved, humanoid.skeleton)))

    assert pops() < 1.5
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(hinges, "eased_bend", hard_stop)
        assert pops() > 2.0


def test_the_stream_keeps_a_restyle_s_elbows_on_their_hinge(walk):
    from stylecast.models.restyle import restyle_rotations

    def bends_elbows_sideways(words):
        return turned(words.reshape(-1, *words.shape[2:]), "LeftLowerArm", 2, 15.0).reshape(words.shape)

    out = restyle_rotations(walk, bends_elbows_sideways).rotations
    hinge = next(h for h in HINGES if h.bone == "LeftLowerArm")
    _, side, _ = parts(out[:, HUMANOID_BONES.index(hinge.bone)], hinge)
    _, side_in, _ = parts(walk[:, HUMANOID_BONES.index(hinge.bone)], hinge)
    assert np.abs(side - side_in).max() < 1e-6


def test_another_skeleton_passes_unchanged():
    q = rot.exp_map(np.random.default_rng(0).normal(size=(5, 7, 3)))
    out = rot.exp_map(np.random.default_rng(1).normal(size=(5, 7, 3)))
    assert np.array_equal(keep_hinges(q, out), out)


def test_the_foot_lock_s_leg_ik_bends_knees_as_hinges():
    """The lock's two-bone IK (``footlock.solve_legs``) on legs turned every way: each knee
    it solves turns about its hinge axis alone, and each ankle lands on its target."""
    from stylecast.motion import footlock as F
    from stylecast.motion.humanoid import humanoid_skeleton_default

    skeleton = humanoid_skeleton_default()
    rng = np.random.default_rng(0)
    q = rot.exp_map(rng.normal(scale=0.3, size=(40, len(HUMANOID_BONES), 3)))
    roots = np.tile([0.0, 90.0, 0.0], (len(q), 1))
    pos, world, _ = F.leg_chain(roots, q, skeleton.offsets)
    target = pos[:, :, 2] + rng.normal(scale=3.0, size=(len(q), 2, 3))
    solved = F.solve_legs(roots, q, skeleton.offsets, target, world[:, :, 2])
    knee = next(h for h in HINGES if h.bone == "LeftLowerLeg")
    for side in range(2):
        flexion, sideways, twist = parts(solved[:, side, 1], knee)
        assert np.abs(sideways).max() < 1e-6 and np.abs(twist).max() < 1e-6
    legs = q.copy()
    legs[:, F.LEG_INDEX[:, :3]] = solved
    reached = F.leg_chain(roots, legs, skeleton.offsets)[0][:, :, 2]
    reachable = np.linalg.norm(target - pos[:, :, 0], axis=-1) < 80.0  # well inside the leg's reach
    assert np.abs(reached - target)[reachable].max() < 0.1
