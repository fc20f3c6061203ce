"""Humanoid retargeting on the real Bandai clips (../shared/data), and the CLI on them."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from bvh import Bvh  # an independent BVH reader (bvh-python), not the project's
from scipy.spatial.transform import Rotation

from stylecast.motion import forward_kinematics
from stylecast.motion.bvh import read_bvh
from stylecast.motion.humanoid import HUMANOID_BONES, Retarget


def sample_clips(root):
    d2 = sorted((root / "dataset-2" / "data").glob("*.bvh.gz"))
    d1 = sorted((root / "dataset-1" / "data").glob("*.bvh"))
    return d2[:: max(1, len(d2) // 8)][:8] + d1[:: max(1, len(d1) // 4)][:4]


def test_humanoid_fk_reproduces_source_positions_within_a_tenth_of_a_millimetre(bandai_root):
    for path in sample_clips(bandai_root):
        clip = read_bvh(path)
        retarget = Retarget.for_clip(clip)
        source_pos, _ = forward_kinematics(clip)
        human_pos, _ = forward_kinematics(retarget.to_humanoid(clip))
        for h, s in enumerate(retarget.bone_source):
            if s >= 0:
                assert np.abs(human_pos[:, h] - source_pos[:, s]).max() < 0.01, (path.name, HUMANOID_BONES[h])


def test_twist_conventions_are_the_same_for_every_clip_of_the_rig(bandai_root):
    found = {tuple(sorted(Retarget.for_clip(read_bvh(p)).twists.items())) for p in sample_clips(bandai_root)}
    assert found == {(("LeftShoulder", 270.0), ("RightShoulder", 270.0), ("RightUpperLeg", 180.0))}


def test_standing_frames_read_as_an_upright_humanoid(bandai_root):
    """Identity is the T-pose: an actor standing with arms down has near-identity spine,
    legs and feet, and upper arms swung down by roughly 60-90 degrees."""
    clip = read_bvh(next((bandai_root / "dataset-2" / "data").glob("dataset-2_walk_normal_*.bvh.gz")))
    human = Retarget.for_clip(clip).to_humanoid(clip).rotations[0]
    angle = lambda bone: np.degrees(Rotation.from_quat(human[HUMANOID_BONES.index(bone)]).magnitude())  # noqa: E731
    for bone in ("Spine", "Chest", "Neck", "Head", "LeftUpperLeg", "RightUpperLeg", "LeftFoot", "RightFoot",
                 "LeftShoulder", "RightShoulder"):
        assert angle(bone) < 35, bone
    for bone in ("LeftUpperArm", "RightUpperArm"):
        assert 50 < angle(bone) < 100, bone


def independent_world_positions(path):
    """World joint positions from bvh-python's parse and scipy, sharing nothing with
    stylecast's reader or FK: Euler channels intrinsic in file order, position channels
    (root) replacing the offset."""
    doc = Bvh(path.read_text())
    names = doc.get_joints_names()
    frames = np.array(doc.frames, dtype=float)
    column, positions, world = 0, {}, {}
    for name in names:
        channels = doc.joint_channels(name)
        values = frames[:, column:column + len(channels)]
        column += len(channels)
        offset = np.array(doc.joint_offset(name), float)
        local_t = np.tile(offset, (len(frames), 1))
        for axis, key in enumerate(("Xposition", "Yposition", "Zposition")):
            if key in channels:
                local_t[:, axis] = values[:, channels.index(key)]
        order = "".join(c[0] for c in channels if c.endswith("rotation"))
        angles = np.stack([values[:, channels.index(f"{a}rotation")] for a in order], axis=1)
        local_r = Rotation.from_euler(order.upper(), angles, degrees=True)
        parent = doc.joint_parent(name)
        if parent is None:
            world[name], positions[name] = local_r, local_t
        else:
            world[name] = world[parent.name] * local_r
            positions[name] = positions[parent.name] + world[parent.name].apply(local_t)
    return positions


def test_convert_humanoid_is_read_by_an_independent_reader_with_the_same_positions(bandai_root, tmp_path):
    source = sorted((bandai_root / "dataset-2" / "data").glob("dataset-2_wave-both-hands_exhausted_*.bvh.gz"))[0]
    out = tmp_path / "humanoid.bvh"
    done = subprocess.run([sys.executable, "-m", "stylecast", "convert", str(source), "-o", str(out), "--humanoid"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    clip = read_bvh(source)
    retarget = Retarget.for_clip(clip)
    source_pos, _ = forward_kinematics(clip)
    theirs = independent_world_positions(out)
    for h, bone in enumerate(HUMANOID_BONES):
        s = retarget.bone_source[h]
        if s >= 0:
            assert np.abs(theirs[bone] - source_pos[:, s]).max() < 0.1, bone  # 1 mm, in cm


def test_info_lists_the_mapping(bandai_root):
    source = sorted((bandai_root / "dataset-1" / "data").glob("*.bvh"))[0]
    done = subprocess.run([sys.executable, "-m", "stylecast", "info", str(source)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "joints    22" in done.stdout and "fps       30" in done.stdout
    assert "21/22 bones mapped" in done.stdout
    assert "UpperChest     -- missing (identity)" in done.stdout
    assert "LeftUpperArm   UpperArm_L" in done.stdout


def test_restyled_humanoid_goes_back_onto_the_source_rig(bandai_root):
    clip = read_bvh(sorted((bandai_root / "dataset-2" / "data").glob("*.bvh.gz"))[3])
    retarget = Retarget.for_clip(clip)
    back = retarget.to_source(retarget.to_humanoid(clip), template=clip)
    a, _ = forward_kinematics(clip)
    b, _ = forward_kinematics(back)
    assert np.abs(a - b).max() < 1e-6
    assert back.skeleton.names == clip.skeleton.names


def test_info_into_a_pipe_nobody_reads_stops_quietly():
    # `stylecast info F | head -3` once ended in a BrokenPipeError traceback. A pipe whose
    # reading end is closed before the command starts fails its first write, every time.
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        clip = Path(__file__).resolve().parents[1] / "daemon" / "clips" / "walk_normal.bvh.gz"
        done = subprocess.run([sys.executable, "-m", "stylecast", "info", str(clip)], stdout=write_end,
                              stderr=subprocess.PIPE, text=True)
    finally:
        os.close(write_end)
    assert done.returncode == 141 and done.stderr == "", done.stderr


@pytest.mark.parametrize("fps", ["0", "-5", "nan", "inf", "1e9"])
@pytest.mark.parametrize("command", ["convert", "restyle"])
def test_a_frame_rate_out_of_range_is_one_sentence(tmp_path, capsys, command, fps):
    # --fps 0 once left the clip as it was without a word, -5 and inf ended in tracebacks,
    # 1e9 asked numpy for 68 GB.
    from stylecast.cli import main

    clip = Path(__file__).resolve().parents[1] / "daemon" / "clips" / "walk_normal.bvh.gz"
    argv = [command, str(clip), "-o", str(tmp_path / "out.bvh"), "--fps", fps]
    try:
        status = main(argv)
    except SystemExit as stop:  # argparse's own refusal
        status = stop.code
    err = capsys.readouterr().err
    assert status == 2 and "must be a frame rate above 0 and at most 1000 frames per second" in err, err
    assert "Traceback" not in err and not (tmp_path / "out.bvh").exists()


@pytest.mark.parametrize("command", [["restyle", "{clip}", "-o", "{out}"],
                                     ["restyle", "{clip}", "-o", "{out}", "--live"],
                                     ["emulate", "--bvh", "{clip}", "--to", "vmc://127.0.0.1:9"],
                                     ["serve", "--source", "bvh://{clip}", "--out", "vmc://127.0.0.1:9"],
                                     ["demo", "{clip}", "--no-view", "--duration", "1"]])
def test_a_bvh_with_no_frames_is_one_sentence_wherever_it_is_played(tmp_path, capsys, command):
    # A valid file (Frames: 0) that `restyle` and `emulate` once ended in tracebacks on.
    import gzip

    demo = gzip.open(Path(__file__).resolve().parents[1] / "daemon" / "clips" / "walk_normal.bvh.gz", "rt").read()
    clip = tmp_path / "empty.bvh"
    clip.write_text(demo.split("MOTION")[0] + "MOTION\nFrames: 0\nFrame Time: 0.0333333\n")
    from stylecast.cli import main

    status = main([a.format(clip=clip, out=tmp_path / "out.bvh") for a in command])
    err = capsys.readouterr().err
    assert status == 2 and "has no frames (its MOTION section is empty); export it again" in err, err
    assert "Traceback" not in err and not (tmp_path / "out.bvh").exists()


@pytest.mark.parametrize("bad", ["missing.bvh"])
def test_info_on_a_missing_file_is_one_sentence(tmp_path, bad):
    done = subprocess.run([sys.executable, "-m", "stylecast", "info", str(tmp_path / bad)], capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.startswith("stylecast: error: ") and "Traceback" not in done.stderr
