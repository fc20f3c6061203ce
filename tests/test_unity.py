"""motion/unity.py: the one BVH <-> Unity conversion, pinned with a known pose.

The pose: the default humanoid in T-pose with LeftUpperArm turned +90 degrees about +Z
in internal space, which raises the left arm straight up (the arm points along +X, the
performer's left, and +90 about +Z takes +X to +Y). Converted to Unity and run through
forward kinematics there (the same formula, converted quantities), the left hand must be
above the left shoulder, on Unity's -X side (the avatar faces +Z, so its left is -X).
Two more poses, the left arm turned forward and the left thigh kicked forward, pin the
facing (+Z in both spaces) and the sign of the quaternion's x.

The check is also run with plausible wrong conventions, each of which must fail it: a
test that also passed for a wrong sign would pin nothing.
"""

from __future__ import annotations

import numpy as np
import pytest

from stylecast.motion import rotations as rot
from stylecast.motion.humanoid import HUMANOID_BONES, HUMANOID_PARENTS, humanoid_skeleton_default
from stylecast.motion.unity import (position_from_unity, position_to_unity, rotation_from_unity,
                                    rotation_to_unity)

J = {b: i for i, b in enumerate(HUMANOID_BONES)}


def fk(root_position, local_rotations, offsets):
    """World positions (J, 3): the same formula in either handedness."""
    world_r = np.empty((len(HUMANOID_BONES), 4))
    world_p = np.empty((len(HUMANOID_BONES), 3))
    for j, p in enumerate(HUMANOID_PARENTS):
        if p < 0:
            world_r[j], world_p[j] = local_rotations[j], root_position
        else:
            world_r[j] = rot.multiply(world_r[p], local_rotations[j])
            world_p[j] = world_p[p] + rot.apply(world_r[p], offsets[j])
    return world_p


def posed(bone: str, axis, degrees: float):
    sk = humanoid_skeleton_default()
    q = rot.identity((len(HUMANOID_BONES),))
    q[J[bone]] = rot.from_euler(np.asarray(axis, float) * degrees, "XYZ")
    return np.array([0.0, 95.0, 0.0]), q, np.asarray(sk.offsets)


def unity_world(pos_fn, rot_fn, root, q, offsets):
    return fk(pos_fn(root), rot_fn(q), pos_fn(offsets))


def arm_raised_checks(pos_fn, rot_fn) -> bool:
    """True when the converted raised-left-arm pose looks right in Unity."""
    w = unity_world(pos_fn, rot_fn, *posed("LeftUpperArm", (0, 0, 1), 90.0))
    hand, shoulder = w[J["LeftHand"]], w[J["LeftUpperArm"]]
    return bool(hand[1] > shoulder[1] + 0.5           # hand well above the shoulder (metres)
                and hand[0] < 0 and shoulder[0] < 0  # on Unity's -X side: the avatar's left
                and abs(hand[0] - shoulder[0]) < 1e-6)  # straight up, not sideways


def arm_forward_checks(pos_fn, rot_fn) -> bool:
    """Left arm turned -90 about +Y internally points forward (+Z); it must in Unity too."""
    w = unity_world(pos_fn, rot_fn, *posed("LeftUpperArm", (0, 1, 0), -90.0))
    hand, shoulder = w[J["LeftHand"]], w[J["LeftUpperArm"]]
    return bool(hand[2] > shoulder[2] + 0.5 and hand[0] < 0)


def leg_kick_checks(pos_fn, rot_fn) -> bool:
    """Left thigh turned -90 about +X internally kicks forward (+Z); a rotation about X
    is what tells a correct quaternion conversion from a merely inverted one."""
    w = unity_world(pos_fn, rot_fn, *posed("LeftUpperLeg", (1, 0, 0), -90.0))
    foot, hip = w[J["LeftFoot"]], w[J["LeftUpperLeg"]]
    return bool(foot[2] > hip[2] + 0.5 and abs(foot[1] - hip[1]) < 1e-6 and foot[0] < 0)


def all_checks(pos_fn, rot_fn) -> bool:
    return (arm_raised_checks(pos_fn, rot_fn) and arm_forward_checks(pos_fn, rot_fn)
            and leg_kick_checks(pos_fn, rot_fn))


def test_internal_pose_is_what_we_think():
    root, q, off = posed("LeftUpperArm", (0, 0, 1), 90.0)
    w = fk(root, q, off)
    assert w[J["LeftHand"], 1] > w[J["LeftUpperArm"], 1] + 50  # cm, internal: raised
    assert w[J["LeftHand"], 0] > 0  # internal left is +X


def test_raised_left_arm_stays_raised_left_arm_in_unity():
    assert arm_raised_checks(position_to_unity, rotation_to_unity)


def test_forward_stays_forward_in_unity():
    assert arm_forward_checks(position_to_unity, rotation_to_unity)


def test_forward_kick_stays_forward_in_unity():
    assert leg_kick_checks(position_to_unity, rotation_to_unity)


def test_t_pose_left_arm_extends_towards_unity_minus_x():
    root, q, off = posed("LeftUpperArm", (0, 0, 1), 0.0)
    w = unity_world(position_to_unity, rotation_to_unity, root, q, off)
    assert w[J["LeftHand"], 0] < w[J["LeftUpperArm"], 0] < 0
    assert np.isclose(w[J["Hips"], 1], 0.95)  # centimetres became metres


WRONG = {
    "quaternion not converted": (position_to_unity, lambda q: np.asarray(q, float)),
    "all quaternion xyz negated": (position_to_unity, lambda q: np.asarray(q, float) * [-1, -1, -1, 1]),
    "quaternion x negated instead": (position_to_unity, lambda q: np.asarray(q, float) * [-1, 1, 1, 1]),
    "position x not negated": (lambda p: np.asarray(p, float) / 100, rotation_to_unity),
    "z-mirror convention": (lambda p: np.asarray(p, float) * [0.01, 0.01, -0.01],
                            lambda q: np.asarray(q, float) * [-1, -1, 1, 1]),
}


@pytest.mark.parametrize("name", sorted(WRONG))
def test_wrong_conventions_fail_the_checks(name):
    pos_fn, rot_fn = WRONG[name]
    assert not all_checks(pos_fn, rot_fn), name


def test_round_trip_and_vectorised():
    rng = np.random.default_rng(0)
    p = rng.normal(size=(5, 7, 3)) * 100
    q = rng.normal(size=(5, 7, 4))
    assert position_to_unity(p).shape == (5, 7, 3)
    np.testing.assert_allclose(position_from_unity(position_to_unity(p)), p)
    np.testing.assert_allclose(rotation_from_unity(rotation_to_unity(q)), q)
    np.testing.assert_allclose(position_to_unity([100.0, 200.0, -300.0]), [-1.0, 2.0, -3.0])
    np.testing.assert_allclose(rotation_to_unity([0.1, 0.2, 0.3, 0.9]), [0.1, -0.2, -0.3, 0.9])


def test_conversion_is_a_homomorphism():
    """Mirroring commutes with composition and with rotating vectors, which is why FK in
    Unity space is the same formula with converted quantities."""
    rng = np.random.default_rng(1)
    a = rot.from_euler(rng.uniform(-180, 180, (20, 3)), "XYZ")
    b = rot.from_euler(rng.uniform(-180, 180, (20, 3)), "XYZ")
    v = rng.normal(size=(20, 3))
    ab = rot.multiply(rotation_to_unity(a), rotation_to_unity(b))
    assert np.all(rot.angle_between(ab, rotation_to_unity(rot.multiply(a, b))) < 1e-6)
    np.testing.assert_allclose(rot.apply(rotation_to_unity(a), position_to_unity(v)),
                               position_to_unity(rot.apply(a, v)), atol=1e-12)
