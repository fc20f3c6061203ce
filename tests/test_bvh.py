"""motion/bvh.py: round trips, channel layouts, encodings, every malformed-file message, Bandai data."""

from __future__ import annotations

import gzip
import itertools
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stylecast.motion import bvh
from stylecast.motion import rotations as rot
from stylecast.motion.bvh import format_bvh, parse_bvh, read_bvh, write_bvh
from stylecast.motion.clip import Clip
from stylecast.motion.errors import UserError
from stylecast.motion.skeleton import Skeleton

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]
POS = ("Xposition", "Yposition", "Zposition")

SMALL = """HIERARCHY
ROOT Hips
{
  OFFSET 1 2 3
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 5 0
    }
  }
  JOINT Leg
  {
    OFFSET 4 -1 0
    CHANNELS 3 Xrotation Yrotation Zrotation
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
1.5 90 -2 10 20 30 0 0 45 1 2 3
-0.5 91 -2.25 -10 -20 -30 5 0 0 -1 -2 -3
"""


def rot_names(order: str) -> tuple[str, ...]:
    return tuple(f"{axis}rotation" for axis in order)


def motion_rows(text: str) -> np.ndarray:
    """The MOTION numbers of BVH text, read independently of the module under test."""
    body = text.split("Frame Time:", 1)[1].split("\n", 1)[1]
    return np.array([[float(v) for v in line.split()] for line in body.splitlines() if line.strip()])


def mixed_skeleton(order: str) -> Skeleton:
    """Root with 6 channels, a 3-channel joint, a 6-channel joint (rotations first) and End Sites."""
    channels = (POS + rot_names(order), rot_names(order), rot_names(order) + POS, rot_names(order[::-1]))
    return Skeleton(("Hips", "Spine", "Arm", "Leg"), (-1, 0, 1, 0),
                    [[0, 0, 0], [0, 10, 0], [3, 0, 0], [0, -8, 1]], channels,
                    end_sites=((2, (1.0, 0.0, 0.0)), (3, (0.0, -2.0, 0.5))))


def canonical_angles(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Euler angles inside scipy's output ranges, away from gimbal lock, so they decompose back unchanged."""
    a = rng.uniform(-179, 179, (*shape, 3))
    a[..., 1] = rng.uniform(-89, 89, shape)
    return a


def clip_from_angles(skeleton: Skeleton, angles: np.ndarray, positions: np.ndarray, fps: float = 30.0) -> Clip:
    quats = np.stack([rot.from_euler(angles[:, j], skeleton.euler_order(j)) for j in range(len(skeleton))], axis=1)
    return Clip(skeleton, quats, positions[:, 0].copy(), fps, positions)


def assert_user_error(match: str, fn, *args) -> str:
    with pytest.raises(UserError) as info:
        fn(*args)
    message = str(info.value)
    assert re.search(match, message), message
    # One sentence: no line break, one final full stop, no second sentence inside.
    assert "\n" not in message and message.endswith("."), message
    assert not re.search(r"\.\s+[A-Z]", message), message
    return message


# ----------------------------------------------------------------------------- reading

def test_reads_hierarchy_and_values_of_a_literal_file():
    clip = parse_bvh(SMALL, "small.bvh")
    sk = clip.skeleton
    assert sk.names == ("Hips", "Spine", "Leg") and sk.parents == (-1, 0, 0)
    np.testing.assert_array_equal(sk.offsets, [[1, 2, 3], [0, 10, 0], [4, -1, 0]])
    assert sk.channels[1] == rot_names("ZXY") and sk.channels[2] == rot_names("XYZ")
    assert sk.end_sites == ((1, (0.0, 5.0, 0.0)),)
    assert clip.fps == 30.0 and clip.num_frames == 2
    np.testing.assert_array_equal(clip.root_positions, [[1.5, 90, -2], [-0.5, 91, -2.25]])
    assert clip.translations is None  # only the root has position channels
    np.testing.assert_allclose(clip.rotations[0, 0], rot.from_euler([10, 20, 30], "ZXY"))
    np.testing.assert_allclose(clip.rotations[1, 2], rot.from_euler([-1, -2, -3], "XYZ"))


def test_crlf_tabs_and_extra_spaces_read_the_same():
    plain = parse_bvh(SMALL, "a.bvh")
    messy = SMALL.replace("  ", "\t").replace(" ", " \t ").replace("\n", "  \r\n") + "\r\n\r\n"
    other = parse_bvh(messy, "b.bvh")
    assert other.skeleton == plain.skeleton and other.skeleton.end_sites == plain.skeleton.end_sites
    np.testing.assert_array_equal(other.rotations, plain.rotations)
    np.testing.assert_array_equal(other.root_positions, plain.root_positions)


def test_brace_on_the_joint_line_and_names_with_spaces():
    text = SMALL.replace("JOINT Leg\n  {", "JOINT Left Leg {")
    clip = parse_bvh(text, "a.bvh")
    assert clip.skeleton.names[2] == "Left Leg"
    assert parse_bvh(format_bvh(clip), "b.bvh").skeleton == clip.skeleton


@pytest.mark.parametrize("order", ORDERS)
def test_channel_values_round_trip_for_every_euler_order(order):
    rng = np.random.default_rng(ORDERS.index(order))
    skeleton = mixed_skeleton(order)
    T, J = 7, len(skeleton)
    positions = np.broadcast_to(skeleton.offsets, (T, J, 3)).copy()
    positions[:, 0] = rng.uniform(-200, 200, (T, 3))
    positions[:, 2] = rng.uniform(-5, 5, (T, 3))
    first = format_bvh(clip_from_angles(skeleton, canonical_angles(rng, (T, J)), positions))
    again = format_bvh(parse_bvh(first, "first.bvh"))
    rows = motion_rows(first)
    assert rows.shape == (T, 6 + 3 + 6 + 3)
    np.testing.assert_allclose(motion_rows(again), rows, atol=1e-4, rtol=0)  # every channel, in degrees / cm
    assert again == first  # and the text is reproduced exactly


@pytest.mark.parametrize("order", ORDERS)
def test_any_rotation_round_trips_within_a_ten_thousandth_degree(order):
    rng = np.random.default_rng(10 + ORDERS.index(order))
    skeleton = mixed_skeleton(order)
    T, J = 50, len(skeleton)
    quats = rng.normal(size=(T, J, 4))
    quats[:5] = rot.from_euler(np.array([[0, 90, 0], [0, -90, 0], [180, 90, 45], [0, 0, 180], [90, 90, 90]])[:, None].repeat(J, 1), order)
    quats /= np.linalg.norm(quats, axis=-1, keepdims=True)
    positions = np.broadcast_to(skeleton.offsets, (T, J, 3)).copy()
    clip = Clip(skeleton, quats, rng.uniform(-100, 100, (T, 3)), 30.0, positions)
    once = parse_bvh(format_bvh(clip), "once.bvh")
    twice = parse_bvh(format_bvh(once), "twice.bvh")
    assert rot.angle_between(once.rotations, clip.rotations).max() < 1e-4
    assert rot.angle_between(twice.rotations, once.rotations).max() < 1e-4
    np.testing.assert_allclose(twice.root_positions, clip.root_positions, atol=1e-6)


def test_position_channels_on_joints_replace_their_offsets():
    # Spine animates only Y; Leg has no position channels and keeps its offset.
    text = SMALL.replace("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 4 Yposition Zrotation Xrotation Yrotation")
    text = text.replace("1.5 90 -2 10 20 30 0 0 45", "1.5 90 -2 10 20 30 12.5 0 0 45").replace("-10 -20 -30 5 0 0", "-10 -20 -30 13 5 0 0")
    clip = parse_bvh(text, "a.bvh")
    assert clip.translations is not None
    np.testing.assert_array_equal(clip.translations[:, 1], [[0, 12.5, 0], [0, 13, 0]])
    np.testing.assert_array_equal(clip.translations[:, 2], [[4, -1, 0], [4, -1, 0]])
    np.testing.assert_array_equal(clip.translations[:, 0], clip.root_positions)
    again = format_bvh(clip)
    assert "CHANNELS 4 Yposition Zrotation Xrotation Yrotation" in again
    np.testing.assert_allclose(motion_rows(again), motion_rows(text), atol=1e-6)


def test_joints_with_fewer_rotation_channels():
    text = (SMALL.replace("CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation", "CHANNELS 3 Xposition Yposition Zposition")
            .replace("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 1 Zrotation")
            .replace("CHANNELS 3 Xrotation Yrotation Zrotation", "CHANNELS 2 Yrotation Xrotation"))
    rows = "MOTION\nFrames: 2\nFrame Time: 0.0333333\n1 2 3 30 10 20\n4 5 6 -30 -10 -20\n"
    text = text.split("MOTION")[0] + rows
    clip = parse_bvh(text, "a.bvh")
    np.testing.assert_allclose(clip.rotations[:, 0], np.tile(rot.identity(), (2, 1)))
    np.testing.assert_allclose(clip.rotations[0, 1], rot.from_euler([30, 0, 0], "ZXY"), atol=1e-12)
    np.testing.assert_allclose(clip.rotations[1, 2], rot.from_euler([-10, -20, 0], "YXZ"), atol=1e-12)
    again = format_bvh(clip)
    assert "CHANNELS 1 Zrotation" in again and "CHANNELS 2 Yrotation Xrotation" in again
    np.testing.assert_allclose(motion_rows(again), motion_rows(text), atol=1e-6)


def test_writer_emits_layout_end_sites_and_frame_header():
    clip = parse_bvh(SMALL, "small.bvh")
    text = format_bvh(clip)
    assert text.count("End Site") == 1 and "OFFSET 0.0 5.0 0.0" in text
    assert "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation" in text
    assert "\nFrames: 2\n" in text and "\nFrame Time: 0.03333333333\n" in text
    again = parse_bvh(text, "again.bvh")
    assert again.skeleton == clip.skeleton and again.skeleton.end_sites == clip.skeleton.end_sites


def test_writer_orders_joints_depth_first():
    # Breadth-first joint order: BVH needs each joint's subtree contiguous, so the writer
    # reorders; reading gives the same joints and motion by name.
    sk = Skeleton(("root", "a", "b", "a1", "b1"), (-1, 0, 0, 1, 2), np.arange(15).reshape(5, 3))
    rng = np.random.default_rng(3)
    q = rot.from_euler(canonical_angles(rng, (4, 5)), "ZXY")
    clip = Clip(sk, q, rng.normal(size=(4, 3)), 30.0)
    back = parse_bvh(format_bvh(clip), "x.bvh")
    assert back.skeleton.names == ("root", "a", "a1", "b", "b1")
    for j, name in enumerate(sk.names):
        k = back.skeleton.index(name)
        assert rot.angle_between(back.rotations[:, k], q[:, j]).max() < 1e-4
        np.testing.assert_array_equal(back.skeleton.offsets[k], sk.offsets[j])


def test_deep_chain_and_zero_frames():
    J = 1200  # deeper than Python's recursion limit: parser and writer must not recurse
    sk = Skeleton([f"j{i}" for i in range(J)], [-1] + list(range(J - 1)), np.ones((J, 3)))
    clip = Clip(sk, rot.identity((0, J)), np.zeros((0, 3)), 24.0)
    back = parse_bvh(format_bvh(clip), "deep.bvh")
    assert back.skeleton == sk and back.num_frames == 0 and back.fps == 24.0


def test_gzip_files_are_read_by_magic_bytes(tmp_path):
    clip = parse_bvh(SMALL, "small.bvh")
    write_bvh(clip, tmp_path / "a.bvh.gz")
    assert (tmp_path / "a.bvh.gz").read_bytes()[:2] == b"\x1f\x8b"
    (tmp_path / "disguised.bvh").write_bytes((tmp_path / "a.bvh.gz").read_bytes())
    for name in ("a.bvh.gz", "disguised.bvh"):
        back = read_bvh(tmp_path / name)
        np.testing.assert_allclose(back.root_positions, clip.root_positions)
        assert back.skeleton == clip.skeleton
    write_bvh(clip, tmp_path / "plain.bvh")
    assert (tmp_path / "plain.bvh").read_text() == format_bvh(clip)


@pytest.mark.parametrize(("frame_time", "fps"), [("0.0333333", 30.0), ("0.008333", 120.0), ("0.0416667", 24.0),
                                                 ("0.0333667", 1 / 0.0333667), ("0.05", 20.0)])
def test_fps_snaps_to_integers_within_1e4th(frame_time, fps):
    clip = parse_bvh(SMALL.replace("0.0333333", frame_time), "a.bvh")
    assert clip.fps == fps


@pytest.mark.parametrize("fps", [30.0, 29.97, 120.0, 59.94, 7.5])
def test_fps_round_trips(fps):
    clip = parse_bvh(SMALL, "a.bvh").replace(fps=fps)
    assert parse_bvh(format_bvh(clip), "b.bvh").fps == pytest.approx(fps, rel=1e-9)


NUMBER_FORMATS = ["%.6f", "%.3e", "%r", "%g", "%.15g", "%+.4f", "%.0f", "%.9f", "%.12f", "%E", "%.2e", "%10.4f"]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.floats(allow_nan=False, allow_infinity=False, min_value=-1e12, max_value=1e12)
                          | st.floats(min_value=-1e-3, max_value=1e-3), st.sampled_from(NUMBER_FORMATS)),
                min_size=3, max_size=90))
def test_numbers_parse_exactly_like_float(pairs):
    tokens = [(fmt % value).strip() for value, fmt in pairs]
    tokens += ["-0.0", ".5", "5.", "+7", "007.250", "1E5", "-1e-05", "123456789.5", "0.1234567890123456789"]
    tokens += ["0"] * (-len(tokens) % 3)
    rows = [" ".join(tokens[i:i + 3]) for i in range(0, len(tokens), 3)]
    text = ("HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 3 Xposition Yposition Zposition\n}\nMOTION\n"
            f"Frames: {len(rows)}\nFrame Time: 0.04\n" + "\n".join(rows))  # no final newline: the last token ends the text
    got = parse_bvh(text, "numbers.bvh").root_positions.ravel()
    want = np.array([float(t) for t in tokens])
    assert np.array_equal(got, want) and np.array_equal(np.signbit(got), np.signbit(want)), (tokens, got - want)


# ----------------------------------------------------------------------------- malformed files

HEADER = SMALL.split("MOTION")[0]
ROWS = SMALL.split("Frame Time: 0.0333333\n")[1]  # two rows, on lines 24 and 25


@pytest.mark.parametrize(("text", "match"), [
    ("", r"empty\.bvh line 1: the file is empty"),
    ("  \n\t\r\n", r"line 1: the file is empty"),
    ("hello world\n", r"line 1: expected HIERARCHY but found 'hello'; this is not a BVH file"),
    (HEADER, r"line 20: there is no MOTION section"),
    (HEADER + "MOTION\nFrame Time: 0.1\n", r"line 22: expected 'Frames: <count>' after MOTION but found 'Frame Time: 0.1'"),
    (HEADER + "MOTION\nFrames: 2.5\n", r"line 22: the frame count '2.5' is not a whole number"),
    (HEADER + "MOTION\nFrames: 2\n" + ROWS, r"line 23: expected 'Frame Time: <seconds>'"),
    (HEADER + "MOTION\nFrames: 2\nFrame Time: 0\n" + ROWS, r"line 23: Frame Time '0' is not a positive number"),
    (HEADER + "MOTION\nFrames: 2\nFrame Time: abc\n" + ROWS, r"line 23: Frame Time 'abc'"),
    (HEADER + "MOTION\nFrames: 2\nFrame Time: 1e999\n" + ROWS, r"line 23: Frame Time '1e999' is not a positive number"),
    (HEADER + "MOTION\nFrames: 2\nFrame Time: 1e-320\n" + ROWS, r"line 23: Frame Time '1e-320' is not a positive number"),
    (SMALL.replace("CHANNELS 3 Xrotation", "CHANNELS 3 Xrot"), r"line 18: unknown channel 'Xrot'; use Xposition"),
    (SMALL.replace("CHANNELS 3 Zrotation", "CHANNELS 4 Zrotation"), r"line 9: CHANNELS declares 4 channels but names 3; make the count match"),
    (SMALL.replace("CHANNELS 3 Zrotation", "CHANNELS Zrotation"), r"line 9: CHANNELS must start with the channel count"),
    (SMALL.replace("Zrotation Xrotation Yrotation\n    End", "Zrotation Zrotation Yrotation\n    End"), r"line 9: a channel is listed twice"),
    (SMALL.replace("OFFSET 0 10 0", "OFFSET 0 ten 0"), r"line 8: OFFSET needs three finite numbers, got '0 ten 0'"),
    (SMALL.replace("OFFSET 0 10 0", "OFFSET 0 nan 0"), r"line 8: OFFSET needs three finite numbers, got '0 nan 0'"),
    (SMALL.replace("JOINT Leg", "JOINT Spine"), r"line 15: joint name 'Spine' is used twice"),
    (SMALL.replace("    }\n  }\n  JOINT Leg", "    }\n  JOINT Leg"), r"line 19: the hierarchy ends with the '\{' of joint 'Hips' from line 3 still open; add the missing '\}'"),
    (SMALL.replace("MOTION", "}\nMOTION"), r"line 21: '\}' after the ROOT's closing '\}'.*remove it"),
    (SMALL.replace("MOTION", "ROOT Other\n{\n}\nMOTION"), r"line 21: a second ROOT"),
    (SMALL.replace("  JOINT Leg", "  Joint Leg"), r"line 15: unexpected 'Joint' inside joint 'Hips'"),
    (SMALL.replace("Frames: 2", "Frames: 3"), r"line 25: the file ends after 2 of the 3 frames that 'Frames:' declares; it is truncated"),
    (SMALL[:-12], r"line 25: the file ends in the middle of frame 2 of 2 \(\d+ of 12 values\); it is truncated"),
    (SMALL.replace("Frames: 2", "Frames: 1"), r"line 25: there are more frame rows than the 1 that 'Frames:' declares"),
    (SMALL.replace("1.5 90 -2 10", "1.5 90 -2"), r"line 24: frame 1 has 11 values but the CHANNELS declare 12; every frame must be one line"),
    (SMALL.replace("-0.5 91 -2.25", "-0.5 91\n-2.25"), r"line 25: frame 2 has 2 values but the CHANNELS declare 12"),
    (SMALL.replace("-10 -20", "-10 abc"), r"line 25: 'abc' is not a number; replace it with a decimal value"),
    (SMALL.replace("-10 -20", "-10 1.2.3"), r"line 25: '1.2.3' is not a number"),
    (SMALL.replace("0 0 45", "0 nan 45"), r"line 24: 'nan' is not a finite number"),
    (SMALL.replace("0 0 45", "0 1e999 45"), r"line 24: '1e999' is not a finite number"),
    (SMALL.replace("Frames: 2", "Frames: 1000000000000"), r"line 22: 1000000000000 frames of 12 channels is more than the 2e\+09 values stylecast reads; split the clip"),
    (HEADER.replace("CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation", "CHANNELS 0")
     .replace("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 0").replace("CHANNELS 3 Xrotation Yrotation Zrotation", "CHANNELS 0")
     + "MOTION\nFrames: 1\nFrame Time: 0.1\n\n", r"line 23: the hierarchy declares no CHANNELS"),
])
def test_malformed_text_gives_one_sentence_naming_file_line_and_fix(text, match):
    name = "empty.bvh" if not text else "bad.bvh"
    message = assert_user_error(match, parse_bvh, text, name)
    assert message.startswith(name + " line ")


def test_too_many_joints_is_refused():
    joints = "".join(f"JOINT j{i}\n{{\nOFFSET 0 0 0\n}}\n" for i in range(bvh.MAX_JOINTS))
    text = f"HIERARCHY\nROOT r\n{{\nOFFSET 0 0 0\n{joints}}}\nMOTION\nFrames: 0\nFrame Time: 1\n"
    assert_user_error(r"line 40001: more than 10000 joints", parse_bvh, text, "big.bvh")


def test_unreadable_files(tmp_path):
    assert_user_error(r"missing\.bvh does not exist; check the path", read_bvh, tmp_path / "missing.bvh")
    assert_user_error(r"is a directory, not a BVH file", read_bvh, tmp_path)
    (tmp_path / "empty.bvh").write_bytes(b"")
    assert_user_error(r"empty\.bvh line 1: the file is empty", read_bvh, tmp_path / "empty.bvh")
    (tmp_path / "bad.bvh.gz").write_bytes(b"\x1f\x8b\x08\x00" + b"not gzip at all")
    assert_user_error(r"bad\.bvh\.gz starts like a gzip file but cannot be decompressed", read_bvh, tmp_path / "bad.bvh.gz")
    (tmp_path / "cut.bvh.gz").write_bytes(gzip.compress(SMALL.encode())[:-20])
    assert_user_error(r"cut\.bvh\.gz starts like a gzip file but cannot be decompressed", read_bvh, tmp_path / "cut.bvh.gz")
    (tmp_path / "trunc.bvh.gz").write_bytes(gzip.compress(SMALL[:-30].encode()))
    assert_user_error(r"trunc\.bvh\.gz line 25: the file ends in the middle of frame 2", read_bvh, tmp_path / "trunc.bvh.gz")
    assert_user_error(r"cannot be written", write_bvh, parse_bvh(SMALL, "a"), tmp_path / "no" / "such" / "dir.bvh")


def test_oversized_files_are_refused_before_reading(tmp_path, monkeypatch):
    monkeypatch.setattr(bvh, "MAX_TEXT_BYTES", 400)
    (tmp_path / "big.bvh").write_text(SMALL * 2)
    assert_user_error(rf"big\.bvh holds {2 * len(SMALL)} bytes, more than the 400 bytes of BVH text stylecast reads; split it", read_bvh, tmp_path / "big.bvh")
    (tmp_path / "bomb.bvh.gz").write_bytes(gzip.compress(b" " * 100_000))  # small on disk, large inside
    assert_user_error(r"bomb\.bvh\.gz decompresses to more than the 400 bytes", read_bvh, tmp_path / "bomb.bvh.gz")


@settings(max_examples=150, deadline=None)
@given(st.data())
def test_any_corruption_ends_in_a_user_error_or_a_clip(data):
    text = SMALL.encode()
    cut = data.draw(st.integers(0, len(text)))
    at = data.draw(st.integers(0, len(text) - 1))
    byte = data.draw(st.sampled_from(b" \n\t{}.-+e0x\x00\xff"))
    mutated = data.draw(st.sampled_from([text[:cut], text[:at] + bytes([byte]) + text[at + 1:], text[:at] + text[at + 1:]]))
    try:
        clip = parse_bvh(mutated, "fuzz.bvh")
    except UserError as e:
        assert str(e).startswith("fuzz.bvh line ") and "\n" not in str(e)
    else:
        assert np.isfinite(clip.rotations).all() and np.isfinite(clip.root_positions).all()


# ----------------------------------------------------------------------------- the Bandai data

def bandai_files(bandai_root, count: int) -> list:
    files = sorted((bandai_root / "dataset-2" / "data").glob("*.bvh.gz"))[:count]
    files += sorted((bandai_root / "dataset-1" / "data").glob("*.bvh"))[:count]
    if not files:
        pytest.skip(f"no BVH files under {bandai_root}")
    return files


def test_bandai_clips_read_and_round_trip(bandai_root, tmp_path):
    for path in bandai_files(bandai_root, 3):
        clip = read_bvh(path)
        sk = clip.skeleton
        assert len(sk) == 22 and sk.names[0] == "joint_Root" and sk.names[1] == "Hips", path
        assert abs(clip.fps - 30.0) < 1e-3 and clip.fps == 30.0, path
        assert clip.translations is not None  # every Bandai joint animates its position channels
        text = gzip.decompress(path.read_bytes()) if path.suffix == ".gz" else path.read_bytes()
        rows = np.array(text.split(b"Frame Time:")[1].split(b"\n", 1)[1].split(), float).reshape(clip.num_frames, -1)
        hips = 6  # columns: joint_Root 0-5, Hips 6-11 (positions first)
        np.testing.assert_array_equal(clip.translations[:, 1], rows[:, hips:hips + 3])
        np.testing.assert_array_equal(clip.root_positions, rows[:, 0:3])
        out = tmp_path / path.name
        write_bvh(clip, out)
        back = read_bvh(out)
        assert back.skeleton == sk and back.skeleton.end_sites == sk.end_sites and back.fps == 30.0
        assert rot.angle_between(back.rotations, clip.rotations).max() < 1e-4
        np.testing.assert_allclose(back.translations, clip.translations, atol=1e-6)


def test_bandai_sample_matches_independent_parse(bandai_root):
    for path in bandai_files(bandai_root, 15)[::2]:
        clip = read_bvh(path)
        text = gzip.decompress(path.read_bytes()) if path.suffix == ".gz" else path.read_bytes()
        rows = np.array(text.split(b"Frame Time:")[1].split(b"\n", 1)[1].split(), float).reshape(clip.num_frames, -1)
        layout = bvh._layout(clip.skeleton.channels, tuple(range(len(clip.skeleton))))
        cols, joints, axes = layout.pos
        assert np.array_equal(clip.translations[:, joints, axes], rows[:, cols]), path
        cols, joints, slots = layout.rot
        angles = rows[:, cols].reshape(clip.num_frames, len(clip.skeleton), 3)
        np.testing.assert_allclose(clip.rotations, rot.from_euler(angles, "ZXY"), atol=1e-12)


def test_chunked_parsing_matches_and_reports_lines_across_chunks(monkeypatch):
    rng = np.random.default_rng(5)
    skeleton = mixed_skeleton("ZXY")
    T, J = 300, len(skeleton)
    positions = np.broadcast_to(skeleton.offsets, (T, J, 3)).copy()
    text = format_bvh(clip_from_angles(skeleton, canonical_angles(rng, (T, J)), positions))
    whole = parse_bvh(text, "whole.bvh")
    monkeypatch.setattr(bvh, "_CHUNK_BYTES", 300)  # a few rows per chunk
    pieces = parse_bvh(text, "pieces.bvh")
    np.testing.assert_array_equal(pieces.rotations, whole.rotations)
    np.testing.assert_array_equal(pieces.translations, whole.translations)
    lines = text.split("\n")
    first_row = lines.index(next(line for line in lines if line.startswith("Frame Time"))) + 2
    bad = lines.copy()
    bad[first_row + 250 - 1] = bad[first_row + 250 - 1].replace(" ", " x ", 1)
    assert_user_error(rf"line {first_row + 250}: frame 251 has 19 values", parse_bvh, "\n".join(bad), "bad.bvh")
    bad[first_row + 250 - 1] = lines[first_row + 250 - 1].replace(" ", " x", 1)
    assert_user_error(rf"line {first_row + 250}: 'x[-\d.]+' is not a number", parse_bvh, "\n".join(bad), "bad.bvh")
    assert_user_error(rf"line {first_row + T - 1}: the file ends after {T} of the 100000000 frames",
                      parse_bvh, text.replace(f"Frames: {T}", "Frames: 100000000"), "many.bvh")
