"""Humanoid retargeting on synthetic rigs whose answers are known."""

import numpy as np
import pytest

from stylecast.motion import Clip, Skeleton, UserError, forward_kinematics
from stylecast.motion import rotations as rot
from stylecast.motion.humanoid import HUMANOID_BONES, Retarget, load_user_map
from tests.rigs import bandai_like_skeleton, mocap_tpose_skeleton


def still_clip(skeleton: Skeleton, frames: int = 3) -> Clip:
    return Clip(skeleton, rot.identity((frames, len(skeleton))), np.tile([0.0, 90.0, 0.0], (frames, 1)), 30.0)


def test_tpose_rig_at_rest_maps_to_identity():
    clip = still_clip(mocap_tpose_skeleton())
    human = Retarget.for_clip(clip).to_humanoid(clip)
    assert np.allclose(rot.angle_between(human.rotations, rot.IDENTITY), 0.0, atol=1e-6)


def test_raised_left_arm_is_one_rotation_about_forward_axis():
    sk = mocap_tpose_skeleton()
    clip = still_clip(sk)
    rotations = clip.rotations.copy()
    rotations[:, sk.index("LeftArm")] = rot.from_euler(np.array([90.0, 0, 0]), "ZXY")  # +X arm -> +Y
    human = Retarget.for_clip(clip).to_humanoid(clip.replace(rotations=rotations))
    angles = rot.angle_between(human.rotations[0], rot.IDENTITY)
    arm = HUMANOID_BONES.index("LeftUpperArm")
    assert angles[arm] == pytest.approx(90.0, abs=1e-6)
    assert np.allclose(np.delete(angles, arm), 0.0, atol=1e-6)
    expected = rot.from_euler(np.array([90.0, 0, 0]), "ZXY")
    assert rot.angle_between(human.rotations[0, arm], expected) < 1e-6


def test_degenerate_rest_pose_gets_a_real_tpose():
    """Bandai-style rigs: every bone along local X at rest; the T-pose must be computed."""
    sk = bandai_like_skeleton()
    retarget = Retarget.build(sk)
    pos = retarget.tpose_positions
    head, hips = pos[sk.index("Head")], pos[sk.index("Hips")]
    assert head[1] > hips[1] + 30  # head above hips
    for side, sign in (("L", 1), ("R", -1)):
        shoulder, hand = pos[sk.index(f"UpperArm_{side}")], pos[sk.index(f"Hand_{side}")]
        assert sign * (hand[0] - shoulder[0]) > 40 and abs(hand[1] - shoulder[1]) < 1  # arms out sideways
        hip, foot = pos[sk.index(f"UpperLeg_{side}")], pos[sk.index(f"Foot_{side}")]
        assert hip[1] - foot[1] > 70 and abs(hip[0] - foot[0]) < 1  # legs straight down
        assert sign * hip[0] > 0  # performer's left is +X


def test_humanoid_fk_reproduces_source_positions_for_random_motion():
    sk = bandai_like_skeleton()
    rng = np.random.default_rng(1)
    T = 20
    clip = Clip(sk, rot.from_euler(rng.uniform(-60, 60, (T, len(sk), 3)), "ZXY"), rng.normal(0, 50, (T, 3)), 30.0)
    retarget = Retarget.for_clip(clip)
    human = retarget.to_humanoid(clip)
    src_pos, _ = forward_kinematics(clip)
    hum_pos, _ = forward_kinematics(human)
    for h, s in enumerate(retarget.bone_source):
        if s >= 0:
            assert np.abs(hum_pos[:, h] - src_pos[:, s]).max() < 1e-3  # 0.01 mm in cm units


def test_inverse_mapping_restores_the_source_motion():
    sk = bandai_like_skeleton()
    rng = np.random.default_rng(2)
    T = 15
    clip = Clip(sk, rot.from_euler(rng.uniform(-60, 60, (T, len(sk), 3)), "ZXY"), rng.normal(0, 50, (T, 3)), 30.0)
    retarget = Retarget.for_clip(clip)
    back = retarget.to_source(retarget.to_humanoid(clip), template=clip)
    a, _ = forward_kinematics(clip)
    b, _ = forward_kinematics(back)
    assert np.abs(a - b).max() < 1e-6
    assert rot.angle_between(back.rotations, clip.rotations).max() < 1e-4


def test_unmappable_skeleton_is_refused_with_advice():
    sk = Skeleton(("root", "thing"), (-1, 0), np.zeros((2, 3)))
    with pytest.raises(UserError, match=r"cannot map skeleton to the humanoid: .*--map FILE"):
        Retarget.build(sk)


def test_user_map_names_odd_joints(tmp_path):
    sk = mocap_tpose_skeleton()
    renamed = Skeleton(tuple("j%d" % i if n == "LeftForeArm" else n for i, n in enumerate(sk.names)),
                       sk.parents, sk.offsets)
    path = tmp_path / "map.json"
    path.write_text('{"j%d": "LeftLowerArm"}' % sk.index("LeftForeArm"))
    retarget = Retarget.build(renamed, load_user_map(path))
    assert retarget.mapped["LeftLowerArm"] == "j%d" % sk.index("LeftForeArm")
    bad = tmp_path / "bad.json"
    bad.write_text('{"x": "LeftElbow"}')
    with pytest.raises(UserError, match="unknown humanoid bones"):
        load_user_map(bad)


def test_missing_upper_chest_is_identity():
    clip = still_clip(bandai_like_skeleton())
    retarget = Retarget.for_clip(clip)
    assert "UpperChest" in retarget.missing
    rng = np.random.default_rng(3)
    moving = clip.replace(rotations=rot.from_euler(rng.uniform(-40, 40, clip.rotations.shape[:2] + (3,)), "ZXY"))
    human = retarget.to_humanoid(moving)
    assert rot.angle_between(human.rotations[:, HUMANOID_BONES.index("UpperChest")], rot.IDENTITY).max() < 1e-6
