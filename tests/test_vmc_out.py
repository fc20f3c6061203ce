"""drivers/vmc/vmc_out.py: the fast VMC encoder against python-osc, the UDP fan-out, oscdump."""

from __future__ import annotations

import os
import re
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from pythonosc.osc_bundle import OscBundle
from pythonosc.osc_message import OscMessage
from scipy.spatial.transform import Rotation

from stylecast.drivers.vmc.osc_packets import decode, encode_message
from stylecast.drivers.vmc.vmc_out import (FrameEncoder, VmcSender, encode_frame, encode_frame_reference,
                                       encode_trackers)
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default

OFFSETS = np.asarray(humanoid_skeleton_default().offsets)


def random_frame(seed: int):
    rng = np.random.default_rng(seed)
    rots = Rotation.random(len(HUMANOID_BONES), random_state=seed).as_quat()
    root = rng.normal(size=3) * [50, 10, 50] + [0, 95, 0]
    offsets = OFFSETS * rng.uniform(0.8, 1.2)
    return root, rots, offsets, float(rng.uniform(0, 1000))


def python_osc_messages(datagram: bytes) -> list[tuple[str, list]]:
    if OscBundle.dgram_is_bundle(datagram):
        bundle = OscBundle(datagram)
        assert bundle.timestamp == 0  # python-osc's IMMEDIATELY: time tag 1
        return [(m.address, m.params) for m in bundle]
    m = OscMessage(datagram)
    return [(m.address, m.params)]


# ------------------------------------------------------------------------- byte literals

def test_byte_literals():
    assert encode_message("/VMC/Ext/T", 1.5) == b"/VMC/Ext/T\x00\x00,f\x00\x00\x3f\xc0\x00\x00"
    assert encode_message("/VMC/Ext/OK", 1) == b"/VMC/Ext/OK\x00,i\x00\x00\x00\x00\x00\x01"
    dg = encode_frame(np.zeros(3), np.tile([0.0, 0.0, 0.0, 1.0], (22, 1)), OFFSETS, 2.0, bundled=False)
    assert dg[0] == (b"/VMC/Ext/Root/Pos\x00\x00\x00,sfffffff\x00\x00\x00root\x00\x00\x00\x00"
                     + b"\x00\x00\x00\x00" * 6 + b"\x3f\x80\x00\x00")
    assert dg[-1] == b"/VMC/Ext/T\x00\x00,f\x00\x00\x40\x00\x00\x00"
    bundled = encode_frame(np.zeros(3), np.tile([0.0, 0.0, 0.0, 1.0], (22, 1)), OFFSETS, 2.0)
    assert bundled[0][:20] == b"#bundle\x00" + b"\x00" * 7 + b"\x01" + b"\x00\x00\x00\x44"  # 68-byte Root


# ------------------------------------------------------------------ fast path == python-osc

@pytest.mark.parametrize("bundled", [True, False])
@pytest.mark.parametrize("root_mode", ["origin", "hips"])
@pytest.mark.parametrize("seed", range(5))
def test_fast_path_bytes_equal_python_osc_builder(bundled, root_mode, seed):
    frame = random_frame(seed)
    fast = encode_frame(*frame, bundled=bundled, root_mode=root_mode)
    assert fast == encode_frame_reference(*frame, bundled=bundled, root_mode=root_mode)


@pytest.mark.parametrize("max_datagram", [400, 1000, 1472, 1500])
def test_bundles_fit_and_keep_message_order(max_datagram):
    frame = random_frame(7)
    bundles = encode_frame(*frame, max_datagram=max_datagram)
    singles = encode_frame(*frame, bundled=False)
    assert all(len(b) <= max_datagram for b in bundles)
    assert all(OscBundle.dgram_is_bundle(b) for b in bundles)
    flat = [m for b in bundles for m in python_osc_messages(b)]
    assert flat == [m for d in singles for m in python_osc_messages(d)]
    assert len(flat) == 1 + len(HUMANOID_BONES) + 2
    assert len(bundles) == (2 if max_datagram >= 1000 else len(bundles))


def test_default_frame_is_two_bundles_under_the_mtu():
    bundles = encode_frame(*random_frame(1))
    assert len(bundles) == 2 and all(len(b) <= 1472 for b in bundles)


@pytest.mark.parametrize("bundled", [True, False])
def test_decodes_identically_with_python_osc_and_ours(bundled):
    root, rots, offsets, t = random_frame(3)
    datagrams = encode_frame(root, rots, offsets, t, bundled=bundled)
    theirs = [m for d in datagrams for m in python_osc_messages(d)]
    ours = []
    for d in datagrams:
        _, msgs = decode(d, lambda reason: pytest.fail(reason))
        ours += [(a, list(args)) for a, _, args in msgs]
    assert ours == theirs
    # ...and the content is the frame: order, names, Unity conversion, Hips = world pose.
    assert [a for a, _ in theirs] == (["/VMC/Ext/Root/Pos"] + ["/VMC/Ext/Bone/Pos"] * 22
                                      + ["/VMC/Ext/OK", "/VMC/Ext/T"])
    assert theirs[0][1] == ["root", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    assert [p[0] for _, p in theirs[1:23]] == list(HUMANOID_BONES)
    bones = np.array([p[1:] for _, p in theirs[1:23]])
    np.testing.assert_allclose(bones[0, :3], root * [-0.01, 0.01, 0.01], rtol=1e-6)
    np.testing.assert_allclose(bones[1:, :3], offsets[1:] * [-0.01, 0.01, 0.01], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(bones[:, 3:], rots * [1, -1, -1, 1], rtol=1e-6, atol=1e-7)
    assert theirs[-2][1] == [1, 3, 0, 1]
    assert theirs[-1][1][0] == pytest.approx(t, rel=1e-6)


def test_hips_root_mode_puts_the_pose_on_the_root():
    root, rots, offsets, t = random_frame(4)
    msgs = [m for d in encode_frame(root, rots, offsets, t, root_mode="hips") for m in python_osc_messages(d)]
    np.testing.assert_allclose(msgs[0][1][1:4], root * [-0.01, 0.01, 0.01], rtol=1e-6)
    np.testing.assert_allclose(msgs[0][1][4:], rots[0] * [1, -1, -1, 1], rtol=1e-6, atol=1e-7)
    assert msgs[1][1] == ["Hips", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, 1e35])
def test_non_finite_frames_are_refused(bad):
    root, rots, offsets, t = random_frame(5)
    rots[4, 2] = bad
    with pytest.raises(ValueError):
        encode_frame(root, rots, offsets, t)
    with VmcSender([("127.0.0.1", 9)]) as sender:
        assert sender.send_frame(root, rots, offsets, t) == 0
        assert sender.counters()["frames_rejected"] == 1 and sender.datagrams_sent == 0


def test_encoder_is_reusable_and_independent_of_input_arrays():
    enc = FrameEncoder()
    a, b = random_frame(1), random_frame(2)
    first = enc.encode(*a)
    enc.encode(*b)
    assert enc.encode(*a) == first  # the template holds no state from earlier frames


def test_many_performers_sent_in_one_call_send_the_bytes_each_sends_alone():
    """The daemon sends every performer's frame of a tick in one call (``VmcOut.send_many``:
    the values of all frames in one pass); each sink must send the bytes its own ``send``
    sends (the fast path, itself held to python-osc's bytes above), with its own layout
    (bundled or not, the root on the hips or at the origin), and a frame with a NaN is
    refused for its sink alone."""
    from stylecast.drivers.vmc.vmc_out import VmcOut

    receivers = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(4)]
    for r in receivers:
        r.bind(("127.0.0.1", 0))
    targets = [[("127.0.0.1", r.getsockname()[1])] for r in receivers]
    frames = [random_frame(seed)[:3] for seed in range(4)]
    bad = (frames[2][0], frames[2][1].copy(), frames[2][2])
    bad[1][5, 1] = np.nan
    frames[2] = bad
    layouts = [dict(bundled=True), dict(bundled=False), dict(bundled=True), dict(bundled=True)]
    together, alone = [[] for _ in receivers], [[] for _ in receivers]
    sinks = [VmcOut(t, tap=got.append, **kw) for t, got, kw in zip(targets, together, layouts)]
    single = [VmcOut(t, tap=got.append, **kw) for t, got, kw in zip(targets, alone, layouts)]
    for out in (sinks[3], single[3]):
        out.sender.encoder = FrameEncoder(bundled=True, root_mode="hips")
    try:
        VmcOut.send_many([(sink, *frame) for sink, frame in zip(sinks, frames)], 12.5)
        for sink, frame in zip(single, frames):
            sink.send(*frame, 12.5)
        assert together == alone
        assert [len(got) for got in together] == [1, 1, 0, 1]  # the NaN frame refused, the others sent
        assert [s.sender.frames_rejected for s in sinks] == [0, 0, 1, 0]
        assert together[3][0] == FrameEncoder(root_mode="hips").encode(*frames[3], 12.5)
        assert together[1][0] == FrameEncoder(bundled=False).encode(*frames[1], 12.5)
        assert receivers[0].recv(65536) == together[0][0][0]  # really on the wire
    finally:
        for out in (*sinks, *single):
            out.close()
        for r in receivers:
            r.close()


def test_trackers_are_encoded_and_bundled():
    from stylecast.drivers.vmc.vmc_parse import TrackerSample

    samples = [TrackerSample("tra", f"T{i}", np.array([10.0 * i, 100.0, 0.0]), np.array([0, 0, 0, 1.0]))
               for i in range(30)]
    datagrams = encode_trackers(samples, time=3.0)
    assert all(len(d) <= 1472 for d in datagrams) and len(datagrams) > 1
    msgs = [m for d in datagrams for m in python_osc_messages(d)]
    assert msgs[0] == ("/VMC/Ext/Tra/Pos", ["T0", 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    assert msgs[-1] == ("/VMC/Ext/T", [3.0])


# ------------------------------------------------------------------------- user errors

@pytest.mark.parametrize("url", ["vmc://127.0.0.1", "vmc://127.0.0.1:99999", "vmc://127.0.0.1:abc",
                                 "udp://127.0.0.1:39539", "vmc://127.0.0.1:39539?fast=1",
                                 "vmc://127.0.0.1:39539?bundled=yes", "vmc://127.0.0.1:0",
                                 "vmc://no-such-host.invalid:39539"])
def test_bad_output_urls_are_user_errors(url):
    with pytest.raises(UserError) as err:
        VmcSender.from_urls([url])
    assert "vmc://" in str(err.value) or "option" in str(err.value)


def test_from_urls_and_bad_ports():
    s = VmcSender.from_urls(["vmc://127.0.0.1:39539?bundled=0", "vmc://localhost:39540"])
    assert not s.encoder.bundled and s.targets == [("127.0.0.1", 39539), ("localhost", 39540)]
    s.close()
    for port in (-1, 70000, "39539", None):
        with pytest.raises(UserError):
            VmcSender([("127.0.0.1", port)])
    with pytest.raises(UserError):
        VmcSender([])


# --------------------------------------------------------------------- real UDP fan-out

def _receiver() -> socket.socket:
    r = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    r.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    r.bind(("127.0.0.1", 0))
    r.settimeout(0.5)
    return r


def _closed_port() -> int:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def _drain(sock: socket.socket, expected: int) -> list[bytes]:
    """Read until ``expected`` datagrams arrived, or 0.5 s of silence, and a bit beyond."""
    got = []
    try:
        while len(got) < expected:
            got.append(sock.recv(65536))
        sock.settimeout(0.05)  # anything extra would be a bug too
        while True:
            got.append(sock.recv(65536))
    except socket.timeout:
        return got


@pytest.mark.parametrize("dead_first", [True, False])
def test_fan_out_continues_when_a_receiver_vanishes(dead_first):
    live_a, live_b = _receiver(), _receiver()
    dead = _closed_port()
    targets = [("127.0.0.1", live_a.getsockname()[1]), ("127.0.0.1", live_b.getsockname()[1])]
    targets.insert(0 if dead_first else 1, ("127.0.0.1", dead))
    frames = 40
    with VmcSender(targets) as sender:
        for k in range(frames):
            sender.send_frame(*random_frame(k))
        stats = sender.counters()
    for live in (live_a, live_b):
        got = _drain(live, 2 * frames)
        live.close()
        assert len(got) == 2 * frames  # every datagram of every frame reached each live receiver
    per = stats["targets"]
    assert per[f"127.0.0.1:{targets[0][1] if dead_first else targets[1][1]}"]["sent"] == 2 * frames
    live_keys = [f"127.0.0.1:{p}" for _, p in targets if p != dead]
    assert all(per[k]["errors"] == {} for k in live_keys)  # no error blamed on a live receiver
    if sys.platform.startswith("linux"):
        assert sum(per[f"127.0.0.1:{dead}"]["errors"].values()) > 0  # the dead one is noticed


def test_unbundled_mode_sends_one_message_per_datagram():
    live = _receiver()
    with VmcSender([("127.0.0.1", live.getsockname()[1])], bundled=False) as sender:
        sender.send_frame(*random_frame(0))
    got = _drain(live, 25)
    live.close()
    assert len(got) == 25 and all(d.startswith(b"/VMC/Ext/") for d in got)
    assert OscMessage(got[-1]).address == "/VMC/Ext/T"


# ----------------------------------------------------------- an independent peer: oscdump

OSCDUMP = "/usr/bin/oscdump"
LINE = re.compile(r"^(?:[0-9a-f]{8}\.[0-9a-f]{8} )?(/\S*) (\S*)(.*)$")


@pytest.mark.skipif(not os.path.exists(OSCDUMP), reason="liblo's oscdump is not installed "
                    "(Debian package liblo-tools); it is the independent OSC peer of this test")
def test_oscdump_reads_our_frames():
    port = _closed_port()
    proc = subprocess.Popen([OSCDUMP, "-L", str(port)], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            text=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(iter(proc.stdout.readline, "")), daemon=True)
    reader.start()
    try:
        probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        deadline = time.monotonic() + 5
        while not any("/stylecast/probe" in ln for ln in lines):  # wait until it listens
            assert time.monotonic() < deadline, "oscdump did not start listening"
            probe.sendto(encode_message("/stylecast/probe", 1), ("127.0.0.1", port))
            time.sleep(0.05)
        probe.close()
        frame = random_frame(11)
        with VmcSender([("127.0.0.1", port)]) as bundled, \
                VmcSender([("127.0.0.1", port)], bundled=False) as unbundled:
            bundled.send_frame(*frame)
            time.sleep(0.05)
            unbundled.send_frame(*frame)
        while sum("/VMC/Ext/T " in ln for ln in lines) < 2:
            assert time.monotonic() < deadline, f"oscdump printed only {lines!r}"
            time.sleep(0.02)
    finally:
        proc.terminate()
        proc.wait(timeout=5)
    parsed = [LINE.match(ln.strip()).groups() for ln in lines if "/VMC/" in ln]
    expected = ([("/VMC/Ext/Root/Pos", "sfffffff")] + [("/VMC/Ext/Bone/Pos", "sfffffff")] * 22
                + [("/VMC/Ext/OK", "iiii"), ("/VMC/Ext/T", "f")])
    assert [(a, t) for a, t, _ in parsed] == expected * 2
    names = [rest.split()[0].strip('"') for a, _, rest in parsed if a == "/VMC/Ext/Bone/Pos"]
    assert names == list(HUMANOID_BONES) * 2
    # oscdump's own float formatting agrees with what we meant to send (6 decimals).
    reference = [m for d in encode_frame(*frame) for m in python_osc_messages(d)]
    for (_, _, rest), (_, params) in zip(parsed[:25], reference):
        printed = rest.split()[1:] if params and isinstance(params[0], str) else rest.split()
        want = params[1:] if params and isinstance(params[0], str) else params
        np.testing.assert_allclose([float(v) for v in printed], want, atol=2e-6)
