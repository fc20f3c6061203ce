"""The foot lock's legs and floor (motion/footlock/legs.py, solve.py): a knee is a hinge that
keeps its side and moves smoothly through full stretch, a planted leg bends the way the restyle
turned it, and a foot is kept above the floor, with the input's clearance near it."""

from __future__ import annotations

import numpy as np
import pytest

from stylecast.motion import rotations as rot
from stylecast.motion.footlock import (LEG_INDEX, LEGS, ContactSettings, FootLock, kept_clearance, leg_chain,
                                       solve_legs)
from stylecast.motion.footlock.solve import CLEARANCE_BAND, CLEARANCE_SLACK
from stylecast.motion.humanoid import HUMANOID_BONES
from tests.footlock_motion import J, SK, ON_INPUT_ANKLES, STANCE, crouched, stepping


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


def test_a_knee_stays_smooth_through_a_heel_strike_past_full_stretch():
    """A bent planted leg whose target swings out 3 mm past full stretch and back within
    three frames, at up to 1.1 cm a frame (a heel strike where the restyled foot lands
    further than the leg reaches: the multistyle model's walks towards youthful). Eased only
    over the last millimetre, the knee stalled at the clamp and folded by 4 cm in the next
    frame, its third difference 24x the target's own (a held-out walk's pop 3.44x the
    input's largest jerk); eased over SOFT_REACH it stays within 10x."""
    n = 60
    q = np.tile(rot.identity((J,)), (n, 1, 1))
    q[:, HUMANOID_BONES.index("LeftLowerLeg")] = rot.exp_map(np.array([np.radians(20.0), 0.0, 0.0]))
    roots = np.tile([0.0, 100.0, 0.0], (n, 1))
    straight, world, _ = leg_chain(roots[:1], np.tile(rot.identity((J,)), (1, 1, 1)), SK.offsets)
    inside = 6.0 - 6.3 * np.exp(-((np.arange(n) - 30) / 5.0) ** 2)  # cm inside full stretch, -0.3 at the least
    target = np.repeat(straight[:, :, 2], n, axis=0) + inside[:, None, None] * [0.0, 1.0, 0.0]
    out = q.copy()
    out[:, LEG_INDEX[:, :3]] = solve_legs(roots, q, SK.offsets, target, np.repeat(world[:, :, 2], n, axis=0))
    knee = leg_chain(roots, out, SK.offsets)[0][:, 0, 1]
    knee_jerk = np.linalg.norm(np.diff(knee, 3, axis=0), axis=-1).max()
    target_jerk = np.linalg.norm(np.diff(target[:, 0], 3, axis=0), axis=-1).max()
    assert knee_jerk < 10 * target_jerk


def test_a_target_the_restyled_leg_already_reaches_is_solved_exactly_near_full_stretch():
    """A leg 3 mm short of full stretch (inside SOFT_REACH) asked to keep its ankle where it
    is: exact, so a leg the restyle left alone is not bent. With the easing fixed at SOFT_REACH
    short of full reach, this ankle was solved 0.35 mm short and the knee moved 2.0 mm (an
    identity restyle of a Bandai walk moved a knee 0.59 mm); the same leg asked 2 mm further
    is still eased, not clamped."""
    from scipy.optimize import brentq

    from stylecast.motion.footlock.legs import SOFT_REACH, SOFT_REACH_LEAST

    q = rot.identity((1, J))
    lower = HUMANOID_BONES.index("LeftLowerLeg")
    roots = np.array([[0.0, 100.0, 0.0]])

    def bent(angle):  # the left leg with its knee folded by ``angle``: joint positions, world rotations
        q[0, lower] = rot.exp_map(np.array([angle, 0.0, 0.0]))
        return leg_chain(roots, q, SK.offsets)[:2]

    reach = np.linalg.norm(np.subtract(*bent(0.0)[0][0, 0, [2, 0]]))
    inside = lambda angle: reach - np.linalg.norm(np.subtract(*bent(angle)[0][0, 0, [2, 0]]))  # noqa: E731
    pos, world = bent(brentq(lambda angle: inside(angle) - 0.3, 0.0, 0.5))  # the ankle 3 mm inside full reach
    assert SOFT_REACH_LEAST < 0.3 < SOFT_REACH
    solved = q.copy()
    solved[:, LEG_INDEX[:, :3]] = solve_legs(roots, q, SK.offsets, pos[:, :, 2], world[:, :, 2])
    after = leg_chain(roots, solved, SK.offsets)[0]
    np.testing.assert_allclose(after[0, 0, :3], pos[0, 0, :3], atol=1e-6)  # hip, knee, ankle where they were
    further = pos[:, :, 2] + [0.0, -0.2, 0.0]  # 2 mm further down: beyond where the leg reaches now
    solved[:, LEG_INDEX[:, :3]] = solve_legs(roots, q, SK.offsets, further, world[:, :, 2])
    miss = np.linalg.norm(leg_chain(roots, solved, SK.offsets)[0][0, 0, 2] - further[0, 0])
    assert 1e-4 < miss < SOFT_REACH / np.e


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
