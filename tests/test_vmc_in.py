"""drivers/vmc/vmc_parse.py and vmc_in.py: parsing byte literals, framing rules, robustness, real loopback."""

from __future__ import annotations

import struct
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pythonosc.osc_message_builder import OscMessageBuilder
from scipy.spatial.transform import Rotation

from stylecast.drivers.vmc.osc_packets import decode, encode_bundle, encode_message, pack_datagrams
from stylecast.drivers.vmc.vmc_in import VmcReceiver
from stylecast.drivers.vmc.vmc_parse import TrackerSample, VmcParser
from stylecast.drivers.vmc.vmc_out import VmcSender, encode_frame, encode_trackers
from stylecast.motion import rotations as rot
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default

SENDER = ("127.0.0.1", 50000)
OFFSETS = np.asarray(humanoid_skeleton_default().offsets)
J = {b: i for i, b in enumerate(HUMANOID_BONES)}
IDENT = (0.0, 0.0, 0.0, 1.0)


def pose_msg(address: str, name: str, *values) -> bytes:
    return encode_message(address, name, *map(float, values))


def bone(name: str, p=(0.0, 0.0, 0.0), q=IDENT) -> bytes:
    return pose_msg("/VMC/Ext/Bone/Pos", name, *p, *q)


def root(p=(0.0, 0.0, 0.0), q=IDENT) -> bytes:
    return pose_msg("/VMC/Ext/Root/Pos", "root", *p, *q)


def t_msg(t: float) -> bytes:
    return encode_message("/VMC/Ext/T", float(t))


def random_frame(seed: int):
    rng = np.random.default_rng(seed)
    return (rng.normal(size=3) * [30, 5, 30] + [0, 95, 0], Rotation.random(22, random_state=seed).as_quat(),
            OFFSETS * rng.uniform(0.9, 1.1), float(seed) / 60)


def feed_all(parser: VmcParser, datagrams, sender=SENDER, now=0.0):
    out = []
    for d in datagrams:
        out += parser.feed(d, sender, now)
    return out


# ------------------------------------------------------------------------- byte literals

S = b"\x3f\x35\x04\xf3"  # float32 sqrt(1/2)
ROOT_LITERAL = (b"/VMC/Ext/Root/Pos\x00\x00\x00" b",sfffffff\x00\x00\x00" b"root\x00\x00\x00\x00"
                + b"\x00\x00\x00\x00" * 6 + b"\x3f\x80\x00\x00")
HIPS_LITERAL = (b"/VMC/Ext/Bone/Pos\x00\x00\x00" b",sfffffff\x00\x00\x00" b"Hips\x00\x00\x00\x00"
                b"\x3f\x00\x00\x00" b"\x3f\x80\x00\x00" b"\x00\x00\x00\x00"  # (0.5, 1, 0) m
                + b"\x00\x00\x00\x00" * 3 + b"\x3f\x80\x00\x00")
# Unity (0, 0, -s, s): the left arm raised, i.e. +90 degrees about +Z internally.
ARM_LITERAL = (b"/VMC/Ext/Bone/Pos\x00\x00\x00" b",sfffffff\x00\x00\x00" b"LeftUpperArm\x00\x00\x00\x00"
               + b"\x00\x00\x00\x00" * 3 + b"\x00\x00\x00\x00" * 2 + b"\xbf\x35\x04\xf3" + S)
T_LITERAL = b"/VMC/Ext/T\x00\x00,f\x00\x00\x40\x00\x00\x00"  # 2.0


def test_byte_literal_frame_unbundled():
    p = VmcParser()
    assert feed_all(p, [ROOT_LITERAL, HIPS_LITERAL, ARM_LITERAL]) == []
    (frame,) = p.feed(T_LITERAL, SENDER, 1.25)
    assert frame.performer == "vmc:127.0.0.1:50000" and frame.sender_time == 2.0
    assert frame.timestamp == 0.0 and frame.bones_updated == 2 and frame.trackers == ()
    pose = frame.pose
    np.testing.assert_allclose(pose.root_position, [-50.0, 100.0, 0.0])  # x mirrored, cm
    assert rot.angle_between(pose.rotations[J["LeftUpperArm"]], rot.from_euler([0, 0, 90], "XYZ")) < 1e-4
    np.testing.assert_allclose(pose.rotations[J["Head"]], IDENT)  # never seen: identity
    expected = OFFSETS.copy()
    expected[J["LeftUpperArm"]] = 0.0  # as sent; the other bones keep defaults until sent
    np.testing.assert_allclose(frame.offsets, expected, atol=1e-9)


def test_byte_literal_bundle():
    body = [ROOT_LITERAL, HIPS_LITERAL, T_LITERAL]
    datagram = b"#bundle\x00" + b"\x00" * 7 + b"\x01" + b"".join(
        struct.pack(">i", len(m)) + m for m in body)
    assert datagram == encode_bundle(body)
    (frame,) = VmcParser().feed(datagram, SENDER, 0.0)
    np.testing.assert_allclose(frame.pose.root_position, [-50.0, 100.0, 0.0])


# ------------------------------------------------------------------------- framing rules

@pytest.mark.parametrize("bundled", [True, False])
def test_our_sender_yields_exactly_one_frame_per_frame(bundled):
    p = VmcParser()
    sent = [random_frame(k) for k in range(5)]
    frames = [feed_all(p, encode_frame(*f, bundled=bundled)) for f in sent]
    assert [len(f) for f in frames] == [1] * 5  # completed by /VMC/Ext/T, inside the frame
    for (root_p, rots, offsets, t), (frame,) in zip(sent, frames):
        assert np.all(rot.angle_between(frame.pose.rotations, rots) < 1e-3)
        np.testing.assert_allclose(frame.pose.root_position, root_p, atol=1e-4)
        np.testing.assert_allclose(frame.offsets[1:], offsets[1:], atol=1e-4)
        assert frame.sender_time == pytest.approx(t, abs=1e-6) and frame.bones_updated == 22


def _messages_without_t(frame) -> list[bytes]:
    msgs = []
    for d in encode_frame(*frame, bundled=False):
        if not d.startswith(b"/VMC/Ext/T\x00"):
            msgs.append(d)
    return msgs


def test_unbundled_stream_without_t_is_framed_by_the_next_root():
    p = VmcParser()
    got = [feed_all(p, _messages_without_t(random_frame(k)), now=k / 60) for k in range(3)]
    assert [len(g) for g in got] == [0, 1, 1]
    assert got[1][0].timestamp == 0.0 and got[2][0].timestamp == pytest.approx(1 / 60)
    assert p.expire(now=1.0)[0].timestamp == pytest.approx(2 / 60)  # the last one, by age


def test_single_bundle_without_t_completes_at_bundle_end():
    p = VmcParser()
    for k in range(3):
        (frame,) = p.feed(encode_bundle(_messages_without_t(random_frame(k))), SENDER, 0.0)
        assert frame.bones_updated == 22


def test_multi_bundle_frames_without_t_are_not_split():
    p = VmcParser()
    got = [feed_all(p, pack_datagrams(_messages_without_t(random_frame(k)), max_datagram=600))
           for k in range(4)]
    # Completed at the end of the bundle that brought the last of the 22 bones: whole.
    assert [len(g) for g in got] == [1] * 4
    assert all(g[0].bones_updated == 22 for g in got)


def test_tracker_only_stream():
    p = VmcParser()
    samples = [TrackerSample("tra", "LHR-1", np.array([10.0, 100.0, 5.0]), rot.from_euler([0, 30, 0], "XYZ")),
               TrackerSample("hmd", "HMD", np.array([0.0, 160.0, 0.0]), np.array(IDENT), local=True)]
    (frame,) = feed_all(p, encode_trackers(samples, time=0.5))
    assert frame.pose is None and len(frame.trackers) == 2 and frame.sender_time == 0.5
    a, b = frame.trackers
    assert (a.kind, a.serial, a.local, b.kind, b.local) == ("tra", "LHR-1", False, "hmd", True)
    np.testing.assert_allclose(a.position, [10.0, 100.0, 5.0], atol=1e-4)
    assert rot.angle_between(a.rotation, samples[0].rotation) < 1e-4


def test_missing_bones_keep_their_previous_value():
    p = VmcParser()
    first = random_frame(1)
    (f1,) = feed_all(p, encode_frame(*first))
    head = rot.from_euler([10, 20, 30], "XYZ")
    (f2,) = feed_all(p, [root(), bone("Head", q=head * [1, -1, -1, 1]), t_msg(1.0)])
    assert f2.bones_updated == 1
    assert rot.angle_between(f2.pose.rotations[J["Head"]], head) < 1e-4
    keep = [j for j in range(22) if j not in (0, J["Head"])]
    np.testing.assert_allclose(f2.pose.rotations[keep], f1.pose.rotations[keep])


def test_root_is_composed_with_hips():
    """Root/Pos is the Hips' parent: a receiver must apply both (VMC marionette spec)."""
    p = VmcParser()
    turn = rot.from_euler([0, 90, 0], "XYZ")  # internal; sent in Unity convention
    (f,) = feed_all(p, [root((1.0, 0.0, 0.0), turn * [1, -1, -1, 1]), bone("Hips", (0.0, 1.0, 0.5)), t_msg(0)])
    # internal: root at (-100, 0, 0) cm turned 90 about Y; Hips local (0, 100, 50) cm
    np.testing.assert_allclose(f.pose.root_position, [-100.0 + 50.0, 100.0, 0.0], atol=1e-4)
    assert rot.angle_between(f.pose.rotations[0], turn) < 1e-4


def test_performers_by_sender_and_by_port():
    p = VmcParser()
    a = feed_all(p, encode_frame(*random_frame(0)), sender=("127.0.0.1", 1000))
    b = feed_all(p, encode_frame(*random_frame(0)), sender=("127.0.0.1", 1001))
    assert {a[0].performer, b[0].performer} == {"vmc:127.0.0.1:1000", "vmc:127.0.0.1:1001"}
    assert sorted(p.performers) == ["vmc:127.0.0.1:1000", "vmc:127.0.0.1:1001"]
    fixed = VmcParser(performer_id="alice")
    c = feed_all(fixed, encode_frame(*random_frame(0)), sender=("10.0.0.2", 1))
    d = feed_all(fixed, encode_frame(*random_frame(0)), sender=("10.0.0.2", 2))
    assert c[0].performer == d[0].performer == "alice" and fixed.performers == ["alice"]
    six = feed_all(VmcParser(), encode_frame(*random_frame(0)), sender=("::1", 7, 0, 0))
    assert six[0].performer == "vmc:[::1]:7"


def test_too_many_performers_and_idle_ones_are_forgotten():
    p = VmcParser(max_performers=2, idle_timeout=1.0)
    for port in (1, 2, 3):
        feed_all(p, encode_frame(*random_frame(0)), sender=("127.0.0.1", port), now=0.0)
    assert p.counters["too_many_performers"] == 2 and len(p.performers) == 2
    p.expire(now=5.0)
    assert p.performers == []
    assert feed_all(p, encode_frame(*random_frame(0)), sender=("127.0.0.1", 3), now=5.0)


# ----------------------------------------------------------------- bad VMC content

def _builder(address, *typed):
    b = OscMessageBuilder(address)
    for value, tag in typed:
        b.add_arg(value, tag)
    return b.build().dgram


BAD_CONTENT = {
    "non_finite": bone("Head", (0.0, float("nan"), 0.0)),
    "non_finite_inf": bone("Head", q=(0.0, float("inf"), 0.0, 1.0)),
    "bad_quaternion": bone("Head", q=(0.0, 0.0, 0.0, 0.0)),
    "wrong_type": _builder("/VMC/Ext/Bone/Pos", ("Head", "s"), *[(1, "i")] * 7),
    "wrong_type_T": _builder("/VMC/Ext/T", ("x", "s")),
    "missing_args": encode_message("/VMC/Ext/Bone/Pos", "Head", 0.0, 1.0),
    "unknown_address": encode_message("/avatar/parameters/Foo", 1.0),
    "ignored_vmc": encode_message("/VMC/Ext/Blend/Val", "A", 0.5),
    "ignored_bone": bone("LeftIndexProximal"),
}


@pytest.mark.parametrize("case", sorted(BAD_CONTENT))
def test_bad_vmc_content_is_dropped_and_counted(case):
    p = VmcParser()
    (before,) = feed_all(p, encode_frame(*random_frame(2)))
    frames = feed_all(p, [root(), BAD_CONTENT[case], t_msg(9.0)])
    reason = case.removesuffix("_inf").removesuffix("_T")
    assert p.counters[reason] == 1
    (after,) = frames
    np.testing.assert_allclose(after.pose.rotations[1:], before.pose.rotations[1:])  # held


def test_extra_trailing_arguments_are_ignored():
    p = VmcParser()
    msgs = [pose_msg("/VMC/Ext/Root/Pos", "root", 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 0, 0, 0),  # v2.1 scale/offset
            encode_message("/VMC/Ext/Bone/Pos", "Hips", 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 7, "extra"),
            encode_message("/VMC/Ext/OK", 1, 3, 0, 1, 99), encode_message("/VMC/Ext/T", 1.0, 2)]
    (frame,) = feed_all(p, msgs)
    np.testing.assert_allclose(frame.pose.root_position, [0.0, 100.0, 0.0])
    assert set(p.counters) <= {"datagrams", "messages", "frames"}


# --------------------------------------------------------------------- malformed OSC

GOOD = bone("Head")
MALFORMED = {
    "empty": b"",
    "not_osc": b"hello world!",
    "truncated": GOOD[:-4],
    "bad_padding": GOOD[:-1],
    "bad_padding_nonzero": GOOD[:18] + b"\x01" + GOOD[19:],  # a non-zero byte after the NUL
    "bad_address": b"/\xff\xfe\x00,f\x00\x00\x00\x00\x00\x00",
    "bad_string": encode_message("/VMC/Ext/Bone/Pos", "x")[:-4] + b"\xff\x00\x00\x00",
    "bad_type_tag": b"/VMC/Ext/T\x00\x00f\x00\x00\x00\x00\x00\x00\x00",
    "bad_type_tag_array": b"/a\x00\x00,[f]\x00\x00\x00\x00\x00\x00\x00\x00",
    "trailing_bytes": encode_bundle([GOOD + b"\x00\x00\x00\x00"]),
    "bad_bundle_header": b"#bundlX\x00" + bytes(8),
    "bad_element_size": b"#bundle\x00" + bytes(7) + b"\x01" + struct.pack(">i", -4),  # hangs python-osc
    "bad_element_size_odd": b"#bundle\x00" + bytes(7) + b"\x01" + struct.pack(">i", 6) + GOOD[:8],
    "oversized_element": b"#bundle\x00" + bytes(7) + b"\x01" + struct.pack(">i", 1 << 20) + GOOD,
    "nested_bundle": encode_bundle([encode_bundle([GOOD])]),
    "truncated_bundle": b"#bundle\x00" + bytes(4),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_osc_is_counted_by_reason(case):
    p = VmcParser()
    assert p.feed(MALFORMED[case], SENDER, 0.0) == []
    reason = case.removesuffix("_nonzero").removesuffix("_array").removesuffix("_odd")
    reason = "truncated" if reason == "truncated_bundle" else reason
    drops = {k: v for k, v in p.counters.items() if k not in ("datagrams", "messages", "frames")}
    assert drops == {reason: 1}


def test_good_messages_around_a_bad_one_in_a_bundle_survive():
    bad = GOOD[:18] + b"\x01" + GOOD[19:]
    p = VmcParser()
    (frame,) = p.feed(encode_bundle([root(), bad, bone("Hips", (0, 1, 0)), t_msg(1)]), SENDER, 0.0)
    assert p.counters["bad_padding"] == 1 and frame.bones_updated == 1


KNOWN_KEYS = {"datagrams", "messages", "frames", "empty", "not_osc", "truncated", "bad_padding", "bad_address",
              "bad_string", "bad_type_tag", "trailing_bytes", "bad_bundle_header", "bad_element_size",
              "oversized_element", "nested_bundle", "wrong_type", "missing_args", "non_finite",
              "bad_quaternion", "unknown_address", "ignored_vmc", "ignored_bone", "too_many_performers"}
VALID = encode_frame(*random_frame(0)) + encode_frame(*random_frame(1), bundled=False)[:4]


# Cheap to draw (hypothesis time dominates otherwise): a valid datagram, a few byte
# overwrites (which also hit size fields and type tags), and a cut point.
MUTATION = st.tuples(st.integers(0, len(VALID) - 1),
                     st.lists(st.tuples(st.integers(0, 1500), st.integers(0, 255)), min_size=1, max_size=4),
                     st.integers(0, 1500))


def mutate(case) -> bytes:
    which, edits, cut = case
    data = bytearray(VALID[which])
    for i, value in edits:
        data[i % len(data)] = value
    return bytes(data[:cut] if cut % 3 == 0 else data)


@settings(max_examples=500, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(MUTATION.map(mutate), st.binary(max_size=64)))
def test_fuzz_never_raises_and_only_counts_known_reasons(datagram):
    p = VmcParser()
    p.feed(datagram, SENDER, 0.0)
    frames = feed_all(p, VALID[:2])  # a good frame still gets through afterwards (it may
    assert frames[-1].bones_updated == 22  # first complete one the garbage left pending)
    assert set(p.counters) <= KNOWN_KEYS


def test_bulk_random_mutations():
    """The same property for 20,000 more cases: hypothesis spends ~3 ms per example
    drawing; a plain RNG keeps the suite fast while widening the net."""
    rng = np.random.default_rng(1234)
    p = VmcParser()
    for k in range(20_000):
        edits = [(int(i), int(v)) for i, v in zip(rng.integers(0, 1500, 3), rng.integers(0, 256, 3))]
        p.feed(mutate((k % len(VALID), edits[: 1 + k % 3], int(rng.integers(0, 1500)))), SENDER, 0.0)
    assert set(p.counters) <= KNOWN_KEYS
    assert sum(v for k, v in p.counters.items() if k not in ("datagrams", "messages", "frames")) > 1000


# ------------------------------------------------- our decoder agrees with python-osc

ARG = st.one_of(
    st.tuples(st.integers(-(2 ** 31), 2 ** 31 - 1), st.just("i")),
    st.tuples(st.floats(width=32, allow_nan=False), st.just("f")),
    st.tuples(st.text(alphabet=st.characters(blacklist_categories=["Cs"], blacklist_characters="\x00"),
                      max_size=12), st.just("s")),
    st.tuples(st.binary(min_size=1, max_size=9), st.just("b")),  # python-osc refuses empty blobs
    st.tuples(st.integers(-(2 ** 63), 2 ** 63 - 1), st.just("h")),
    st.tuples(st.floats(allow_nan=False), st.just("d")),
    st.sampled_from([(True, "T"), (False, "F"), (None, "N")]),
)


@settings(max_examples=150, deadline=None, database=None)
@given(st.from_regex(r"/[A-Za-z0-9/_]{0,20}", fullmatch=True), st.lists(ARG, max_size=10))
def test_decoder_matches_python_osc(address, args):
    from pythonosc.osc_message import OscMessage

    b = OscMessageBuilder(address)
    for value, tag in args:
        b.add_arg(value, tag)
    dgram = b.build().dgram
    for datagram in (dgram, encode_bundle([dgram])):
        errors = []
        _, msgs = decode(datagram, errors.append)
        assert errors == []
        ((addr, tags, values),) = msgs
        theirs = OscMessage(dgram)
        assert addr == theirs.address and list(values) == theirs.params
        assert tags == "".join(t for _, t in args)


# ------------------------------------------------------------ real loopback UDP sockets

@pytest.mark.parametrize("bundled", [True, False])
def test_round_trip_over_loopback(bundled):
    sent = [random_frame(k) for k in range(10)]
    with VmcReceiver("127.0.0.1", 0) as receiver, VmcSender([receiver.address], bundled=bundled) as sender:
        for f in sent:
            sender.send_frame(*f)
        frames = []
        deadline = time.monotonic() + 5
        while len(frames) < len(sent) and time.monotonic() < deadline:
            frames += receiver.poll(timeout=0.1)
    assert len(frames) == len(sent)
    for (root_p, rots, offsets, t), frame in zip(sent, frames):
        assert frame.performer.startswith("vmc:127.0.0.1:")
        assert np.all(rot.angle_between(frame.pose.rotations, rots) < 1e-3)
        np.testing.assert_allclose(frame.pose.root_position, root_p, atol=1e-4)
        assert frame.sender_time == pytest.approx(t, abs=1e-6)
    assert receiver.counters["frames"] == len(sent)


def test_background_thread_mode_and_hips_root_mode():
    with VmcReceiver("127.0.0.1", 0) as receiver, \
            VmcSender([receiver.address], root_mode="hips") as sender:
        receiver.start()
        f = random_frame(3)
        sender.send_frame(*f)
        frames = []
        deadline = time.monotonic() + 5
        while not frames and time.monotonic() < deadline:
            frames = receiver.poll(timeout=0.2)
        receiver.stop()
    (frame,) = frames
    np.testing.assert_allclose(frame.pose.root_position, f[0], atol=1e-4)
    assert np.all(rot.angle_between(frame.pose.rotations, f[1]) < 1e-3)


def test_receiver_user_errors():
    with VmcReceiver("127.0.0.1", 0) as taken:
        with pytest.raises(UserError, match="choose another"):
            VmcReceiver("127.0.0.1", taken.address[1])
    with pytest.raises(UserError):
        VmcReceiver("no-such-host.invalid", 39540)
    with pytest.raises(UserError):
        VmcReceiver("127.0.0.1", 70000)
    with pytest.raises(UserError, match="unknown option"):
        VmcReceiver.from_url("vmc://127.0.0.1:0?bogus=1")
    with VmcReceiver.from_url("vmc://127.0.0.1:0?performer=alice") as r:
        assert r.parser.performer_id == "alice"


def test_daemon_source_factory():
    from stylecast.drivers.sources import open_source

    src = open_source("vmc://127.0.0.1:0?name=alice", "p0")
    try:
        src.start(0.0)
        with VmcSender([src.receiver.address]) as sender:
            samples = [TrackerSample("tra", "waist", np.array([0.0, 100.0, 0.0]), np.array(IDENT))]
            sender.send_datagrams(encode_trackers(samples))
            sender.send_frame(*random_frame(0))
        poses, deadline = [], time.monotonic() + 5
        while not poses and time.monotonic() < deadline:
            poses = src.poll(time.monotonic())
            time.sleep(0.01)
        assert [p.performer for p in poses] == ["alice"]
        assert list(src.trackers) == [("tra", "waist", False)]
        assert src.counters()["frames"] == 1
    finally:
        src.close()
    with pytest.raises(UserError, match="unknown option"):
        open_source("vmc://127.0.0.1:0?loop=1", "p0")


def test_a_t_sender_repeating_root_in_each_bundle_is_not_split():
    p = VmcParser()
    for k in range(4):
        msgs = _messages_without_t(random_frame(k))
        bundles = [encode_bundle([root(), *msgs[1:12]]), encode_bundle([root(), *msgs[12:], t_msg(k)])]
        frames = feed_all(p, bundles)
        if k > 0:  # from the first T on, T alone frames this sender
            (frame,) = frames
            assert frame.bones_updated == 22
