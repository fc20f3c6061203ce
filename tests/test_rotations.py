"""The hand-written hot-path quaternion algebra agrees with scipy's Rotation."""

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from stylecast.motion import rotations as rot


def random_quats(n, seed):
    return Rotation.random(n, random_state=seed).as_quat()


def test_multiply_matches_scipy():
    a, b = random_quats(500, 1), random_quats(500, 2)
    expected = (Rotation.from_quat(a) * Rotation.from_quat(b)).as_quat()
    assert rot.angle_between(rot.multiply(a, b), expected).max() < 1e-9


def test_exp_and_log_maps_match_scipy():
    q = random_quats(300, 7)
    v = Rotation.from_quat(q).as_rotvec()
    v[:5] *= 1e-9  # near identity
    assert np.abs(rot.log_map(Rotation.from_rotvec(v).as_quat()) - v).max() < 1e-9
    assert rot.angle_between(rot.exp_map(v), Rotation.from_rotvec(v).as_quat()).max() < 1e-9
    assert np.abs(rot.log_map(-Rotation.from_rotvec(v).as_quat()) - v).max() < 1e-9  # sign of q


def test_slerp_matches_scipy_including_short_arc_and_near_equal():
    a, b = random_quats(300, 3), random_quats(300, 4)
    b[:50] = -b[:50]  # same rotations, opposite sign: must take the short arc
    b[50:60] = a[50:60] + 1e-9  # nearly equal
    b[50:60] /= np.linalg.norm(b[50:60], axis=1, keepdims=True)
    t = np.random.default_rng(5).uniform(0, 1, 300)
    ours = rot.slerp(a, b, t)
    for i in range(300):
        s = Slerp([0, 1], Rotation.from_quat([a[i], b[i]]))(t[i]).as_quat()
        assert rot.angle_between(ours[i], s) < 1e-6


def test_from_euler_matches_scipy_every_order():
    angles = np.random.default_rng(0).uniform(-400, 400, (500, 3))
    for order in ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"):
        expected = Rotation.from_euler(order, angles, degrees=True).as_quat()
        np.testing.assert_allclose(rot.from_euler(angles, order), expected, atol=1e-15)


def test_euler_round_trip_every_order():
    q = random_quats(200, 6)
    for order in ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"):
        back = rot.from_euler(rot.to_euler(q, order), order)
        assert rot.angle_between(q, back).max() < 1e-6


def test_bvh_order_means_intrinsic_product():
    """"ZXY" channels mean R = Rz @ Rx @ Ry (BVH convention)."""
    z, x, y = 30.0, -20.0, 50.0
    m = (Rotation.from_euler("z", z, degrees=True) * Rotation.from_euler("x", x, degrees=True)
         * Rotation.from_euler("y", y, degrees=True))
    assert rot.angle_between(rot.from_euler(np.array([z, x, y]), "ZXY"), m.as_quat()) < 1e-9


def test_swing_takes_direction_onto_target_and_handles_opposites():
    q = rot.swing(np.array([0, 1.0, 0]), np.array([0, -1.0, 0]), np.array([0, 0, 1.0]))
    assert np.allclose(rot.apply(q, np.array([0, 1.0, 0])), [0, -1, 0], atol=1e-9)
    assert np.allclose(rot.apply(q, np.array([0, 0, 1.0])), [0, 0, 1], atol=1e-9)  # turned about forward


def test_apply_equals_scipy_for_random_rotations_and_broadcast_shapes():
    rng = np.random.default_rng(3)
    q = Rotation.random(200, random_state=4).as_quat().reshape(10, 20, 4)
    v = rng.normal(size=(10, 20, 3))
    expected = Rotation.from_quat(q.reshape(-1, 4)).apply(v.reshape(-1, 3)).reshape(10, 20, 3)
    np.testing.assert_allclose(rot.apply(q, v), expected, atol=1e-12)
    np.testing.assert_allclose(rot.apply(q, v[0, 0]), Rotation.from_quat(q.reshape(-1, 4)).apply(v[0, 0]).reshape(10, 20, 3),
                               atol=1e-12)  # one vector, many rotations
