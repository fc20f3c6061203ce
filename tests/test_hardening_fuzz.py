"""Malformed input never stops the daemon (issue 7, part 1): VMC and control ports, serial.

How the datagram count is reached, honestly: 200,000 VMC datagrams and 100,000 control
datagrams go through the daemon *in-process*: the VMC ones are fed to the same
``VmcParser.feed`` the socket thread calls, from a source the daemon polls on its own
thread (so every frame junk manages to complete walks the whole pipeline: session,
words, restyler, blender, VMC encoder), and the control ones to ``ControlServer.handle``,
the function the control socket thread calls, while the daemon ticks. A further 20,000
+ 20,000 datagrams go over real loopback UDP to a live daemon's ``vmc://`` input and
control ports. Sending 300,000 over real UDP would take minutes on a loaded CI box; the
in-process part runs the same parsing code path that the socket feeds.

The daemon runs on a ``FakeClock`` throughout: the output clock never drops a tick for
being late, so "the legitimate stream lost no frame" is an exact statement whatever the
machine's load (a real-clock run under flood is tests/test_hardening_flood.py).

Serial: 1 MiB of random bytes with valid, CRC-valid-but-bad and corrupt frames mixed in,
through ``FrameDecoder`` in random read sizes, and a share of it through a real pyserial
``loop://`` port and ``SerialTrackerSource``.
"""

from __future__ import annotations

import math
import socket
import threading
import time
from collections import Counter

import numpy as np
import pytest

from stylecast.motion.clock import FakeClock
from stylecast.daemon.config import DaemonConfig
from stylecast.daemon.control import ControlServer, parse_command
from stylecast.daemon.engine import Daemon
from stylecast.daemon.restylers import IdentityRestyler, StandInRestyler
from stylecast.drivers.vmc.osc_packets import decode, encode_message
from stylecast.drivers.sources import Source, open_source
from stylecast.drivers.vmc.vmc_parse import VmcParser
from stylecast.drivers.vmc.vmc_out import encode_frame
from stylecast.motion.bvh import write_bvh
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default

from .hardening_junk import CLASSES, CONTROL_MUST, VMC_MUST, JunkGenerator, control_seeds, vmc_seeds
from .test_daemon import walk_clip

J = len(HUMANOID_BONES)
SENDER = ("127.0.0.1", 45678)
VMC_DECODE_REASONS = ("empty", "not_osc", "truncated", "bad_padding", "bad_address", "bad_string", "bad_type_tag",
                      "trailing_bytes", "bad_bundle_header", "bad_element_size", "oversized_element", "nested_bundle")
VMC_CONTENT_REASONS = ("wrong_type", "missing_args", "non_finite", "bad_quaternion", "unknown_address",
                       "ignored_vmc", "ignored_bone", "too_many_performers")
VMC_REASONS = VMC_DECODE_REASONS + VMC_CONTENT_REASONS
CONTROL_REASONS = tuple(f"malformed_{r}" for r in VMC_DECODE_REASONS) + ("unknown_address", "bad_arguments",
                                                                          "queue_full")
EMPTY_BUNDLE_LEN = 16  # "#bundle\0" + time tag: valid OSC that carries nothing


def _rejections(counters, reasons) -> int:
    return sum(counters.get(r, 0) for r in reasons)


class Tally:
    """Per-datagram outcome: rejected (some reason counted), accepted, or empty bundle."""

    def __init__(self):
        self.rejected = 0
        self.accepted: list[bytes] = []
        self.empty = 0
        self.by_class = Counter()
        self.missing_reason: list[tuple[str, bytes]] = []
        self.silent: list[bytes] = []

    def record(self, datagram: bytes, cls: str, before: dict, after, reasons, must: dict, used_messages: int):
        delta = {r: after.get(r, 0) - before.get(r, 0) for r in reasons}
        rejected = sum(delta.values())
        self.by_class[cls] += 1
        if rejected:
            self.rejected += 1
        elif used_messages:
            self.accepted.append(datagram)
        elif len(datagram) == EMPTY_BUNDLE_LEN and datagram.startswith(b"#bundle\x00"):
            self.empty += 1
        else:
            self.silent.append(datagram)  # neither used nor counted: the bug this test hunts
        if cls in must and not any(delta.get(r, 0) for r in must[cls]):
            self.missing_reason.append((cls, datagram))


class FedVmcSource(Source):
    """A ``vmc://`` performer whose datagrams come from a generator instead of a socket.

    Its ``poll`` does what ``VmcSource.poll`` does with a receiver (``VmcParser.feed`` for
    every waiting datagram, then ``expire``), on the daemon's thread, so the daemon takes
    whatever frames the junk completes through its whole pipeline."""

    def __init__(self, performer: str, datagrams: list[bytes], classes, per_tick: int):
        self.performer = performer
        self.parser = VmcParser(performer)
        self.datagrams, self.classes, self.per_tick = datagrams, classes, per_tick
        self.next = 0
        self.tally = Tally()
        self.frames_completed = []

    def poll(self, now):
        frames = []
        p = self.parser
        stop = min(self.next + self.per_tick, len(self.datagrams))
        for i in range(self.next, stop):
            d = self.datagrams[i]
            before = dict(p.counters)
            got = p.feed(d, SENDER, now)
            frames += got
            used = (p.counters["messages"] - before.get("messages", 0)
                    - _rejections(p.counters, VMC_CONTENT_REASONS) + _rejections(before, VMC_CONTENT_REASONS))
            self.tally.record(d, CLASSES[self.classes[i]], before, p.counters, VMC_REASONS, VMC_MUST, used)
        self.next = stop
        frames += p.expire(now)
        self.frames_completed += frames
        return [f.pose for f in frames if f.pose is not None]

    @property
    def finished(self):
        return False

    def counters(self):
        return dict(self.parser.counters)


def _python_osc_messages(datagram: bytes) -> int:
    """Messages in ``datagram`` according to python-osc (the independent reference)."""
    from pythonosc.osc_bundle import OscBundle
    from pythonosc.osc_message import OscMessage

    if OscBundle.dgram_is_bundle(datagram):
        def count(b):
            return sum(count(e) if isinstance(e, OscBundle) else 1 for e in b)

        return count(OscBundle(datagram))
    OscMessage(datagram)
    return 1


def _check_accepted_with_python_osc(accepted: list[bytes], limit: int = 1500) -> None:
    rng = np.random.default_rng(0)
    sample = [accepted[i] for i in rng.permutation(len(accepted))[:limit]]
    for d in sample:
        ours = decode(d, lambda reason: pytest.fail(f"accepted datagram has a decode error {reason}"))[1]
        assert _python_osc_messages(d) == len(ours), d[:80]


def legit_clip_url(tmp_path, frames=300) -> str:
    """A humanoid clip written to disk and replayed through the real bvh:// source."""
    path = tmp_path / "legit.bvh"
    write_bvh(walk_clip(frames), path)
    return f"bvh://{path}?loop=1"


def _contiguous(indices) -> bool:
    return list(indices) == list(range(len(indices)))


# ------------------------------------------------------------------- VMC, in-process

def test_200k_junk_vmc_datagrams_through_the_daemon_pipeline(tmp_path):
    n = 200_000
    datagrams, classes = JunkGenerator(vmc_seeds(), seed=1).batch(n)
    junk = FedVmcSource("junk", datagrams, classes, per_tick=250)
    legit = open_source(legit_clip_url(tmp_path), "p0")
    frames: dict[str, list] = {}
    daemon = Daemon(DaemonConfig(hop=15, control="off"), [legit, junk], StandInRestyler(), FakeClock(),
                    frame_taps=[lambda f: frames.setdefault(f.performer, []).append(f)], log_status=False)
    try:
        daemon.start()
        while junk.next < n:
            daemon.step()
        for _ in range(30):  # and a little more, with no junk left
            daemon.step()
    finally:
        daemon.close()
    t = junk.tally
    c = junk.parser.counters
    reasons = {r: c[r] for r in VMC_REASONS if c[r]}
    print(f"\nVMC fuzz, {n} datagrams by class: {dict(t.by_class)}")
    print(f"rejected {t.rejected}, accepted as valid {len(t.accepted)}, empty bundles {t.empty}; "
          f"reason counters: {reasons}")
    # Every datagram was seen and ended up somewhere; none vanished without a count.
    assert c["datagrams"] == n
    assert t.rejected + len(t.accepted) + t.empty == n and not t.silent, t.silent[:3]
    assert sum(reasons.values()) >= t.rejected  # a bundle may carry several bad messages
    # Classes that can only be wrong were each counted under the right reason.
    assert not t.missing_reason, t.missing_reason[:3]
    for reason in ("truncated", "bad_padding", "bad_type_tag", "nested_bundle", "oversized_element",
                   "bad_element_size", "non_finite", "unknown_address", "bad_quaternion", "not_osc"):
        assert reasons.get(reason, 0) > 100, reason  # the counter exists and was really exercised
    # What we accepted is valid OSC by an independent parser too.
    _check_accepted_with_python_osc(t.accepted)
    # Whatever junk frames got through are finite, unit-quaternion poses...
    for f in junk.frames_completed:
        if f.pose is not None:
            assert np.isfinite(f.pose.root_position).all() and np.isfinite(f.pose.rotations).all()
            assert np.allclose(np.linalg.norm(f.pose.rotations, axis=1), 1.0, atol=1e-6)
    # ...and so is everything the daemon sent for either performer.
    for f in frames["p0"] + frames.get("junk", []):
        assert np.isfinite(f.rotations).all() and np.isfinite(f.root_position).all()
    # The legitimate performer: one new frame on every tick, none missing.
    p0 = frames["p0"]
    assert _contiguous([f.index for f in p0]) and len(p0) == daemon.ticks - daemon.settings.delay
    assert all(a is not b for a, b in zip(p0, p0[1:]))  # never a held (repeated) frame
    assert daemon.sessions[0].held == 0 and daemon.sessions[0].skipped == 0
    # The parser is not poisoned: a valid frame still decodes exactly.
    q = np.tile([0.0, 0.0, 0.0, 1.0], (J, 1))
    p = junk.parser
    got = [fr for d in encode_frame(np.array([0.0, 95.0, 0.0]), q, humanoid_skeleton_default().offsets, 1.0)
           for fr in p.feed(d, SENDER, 1e6)]
    assert len(got) == 1 and got[0].bones_updated == J
    np.testing.assert_allclose(got[0].pose.root_position, [0.0, 95.0, 0.0], atol=1e-4)


# --------------------------------------------------------------- control, in-process

def test_100k_junk_control_datagrams_while_the_daemon_ticks(tmp_path, caplog):
    n = 100_000
    datagrams, classes = JunkGenerator(control_seeds(("p0", "nobody")), seed=2, kind="control").batch(n)
    loads = []
    active = [0, 0]  # loaders running now, most ever at once
    lock = threading.Lock()

    def loader(name):
        with lock:
            loads.append(name)
            active[0] += 1
            active[1] = max(active[1], active[0])
        time.sleep(0.01)
        with lock:
            active[0] -= 1
        return IdentityRestyler()

    frames = []
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # where status replies go
    sink.bind(("127.0.0.1", 0))
    sink.setblocking(False)
    addr = sink.getsockname()
    daemon = Daemon(DaemonConfig(hop=15, control="127.0.0.1:0"), [open_source(legit_clip_url(tmp_path), "p0")],
                    StandInRestyler(), FakeClock(), frame_taps=[frames.append], model_loader=loader,
                    log_status=False)
    server = daemon.control
    tally = Tally()
    accepted_commands = []
    replies = 0
    try:
        daemon.start()
        for i, d in enumerate(datagrams):
            before = dict(server.counts)
            server.handle(d, addr)  # what the control thread does with each datagram
            used = server.counts["accepted"] - before.get("accepted", 0)
            if used:
                accepted_commands += list(server.commands)[-used:]
            tally.record(d, CLASSES[classes[i]], before, server.counts, CONTROL_REASONS, CONTROL_MUST, used)
            if i % 200 == 199:
                daemon.step()  # applies the queued commands on the daemon's thread
                while True:
                    try:
                        sink.recv(65536)
                        replies += 1
                    except BlockingIOError:
                        break
        for _ in range(30):
            daemon.step()
    finally:
        daemon.close()
        sink.close()
    counts = {k: v for k, v in server.counts.items() if v}
    print(f"\ncontrol fuzz, {n} datagrams: {counts}; model loads {len(loads)}, status replies {replies}")
    assert server.counts["datagrams"] == n
    assert tally.rejected + len(tally.accepted) + tally.empty == n and not tally.silent, tally.silent[:3]
    assert not tally.missing_reason, tally.missing_reason[:3]
    for reason in ("malformed_truncated", "malformed_bad_padding", "malformed_nested_bundle", "unknown_address",
                   "bad_arguments", "malformed_bad_element_size", "malformed_oversized_element"):
        assert counts.get(reason, 0) > 100, reason
    assert server.counts["queue_full"] == 0  # drained every tick: nothing lost to the bound
    _check_accepted_with_python_osc(tally.accepted)
    # Whatever was accepted is a sane command: finite values in range, bounded strings.
    assert accepted_commands
    for command, value, performer, _ in accepted_commands:
        if command in ("intensity", "crossfade"):
            assert math.isfinite(value) and 0.0 <= value <= (1.0 if command == "intensity" else 60.0)
        elif command == "bypass":
            assert isinstance(value, bool)
        elif command in ("direction", "model"):
            assert isinstance(value, str) and 0 < len(value) <= 512
        assert performer is None or isinstance(performer, str)
    # The daemon kept going: one frame per tick for the legitimate performer, none missing.
    assert _contiguous([f.index for f in frames]) and len(frames) == daemon.ticks - daemon.settings.delay
    assert all(np.isfinite(f.rotations).all() for f in frames)
    # Model requests are coalesced: a flood of them never becomes a flood of loader threads.
    model_requests = sum(1 for c in accepted_commands if c[0] == "model")
    assert model_requests > 100 and active[1] == 1 and len(loads) < model_requests
    # Refused commands (unknown performers, directions the model lacks) are counted, and
    # the log stays short however many there were.
    assert daemon.control_errors > 100
    assert len(caplog.records) < 60, Counter(r.getMessage()[:40] for r in caplog.records).most_common(3)


def test_accepted_control_values_are_finite():
    """Non-finite numbers are refused as bad arguments rather than clamped into range."""
    for value in (float("inf"), float("-inf"), float("nan")):
        assert parse_command("/stylecast/intensity", "f", (value,)) == (None, "bad_arguments")
        assert parse_command("/stylecast/crossfade", "f", (value,)) == (None, "bad_arguments")
    assert parse_command("/stylecast/intensity", "f", (7.5,)) == ("intensity", 1.0, None)


# ------------------------------------------------------------------ live, real UDP

def _free_port_pair() -> tuple[socket.socket, socket.socket]:
    for _ in range(50):
        a = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        a.bind(("127.0.0.1", 0))
        b = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            b.bind(("127.0.0.1", a.getsockname()[1] + 1))
            return a, b
        except OSError:
            a.close()
            b.close()
    raise RuntimeError("no two consecutive free UDP ports")


def _wait(predicate, timeout: float = 30.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.001)
    return predicate()


def _drain(sock, into: list) -> None:
    while True:
        try:
            into.append(sock.recv(65536))
        except BlockingIOError:
            return


def test_live_daemon_takes_40k_junk_datagrams_on_its_ports_without_losing_a_frame(tmp_path):
    n = 20_000
    vmc_junk, vmc_classes = JunkGenerator(vmc_seeds(), seed=3).batch(n)
    ctl_junk, _ = JunkGenerator(control_seeds(("p0",)), seed=4, kind="control").batch(n)
    out_p0, out_junk = _free_port_pair()
    for s in (out_p0, out_junk):
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        s.setblocking(False)
    port = out_p0.getsockname()[1]
    sources = [open_source(legit_clip_url(tmp_path), "p0"), open_source("vmc://127.0.0.1:0?name=junk", "p1")]
    received: list[bytes] = []
    ticks_with_p0 = []
    daemon = Daemon(DaemonConfig(hop=15, control="127.0.0.1:0", out=[f"vmc://127.0.0.1:{port}"]), sources,
                    StandInRestyler(), FakeClock(), log_status=False,
                    frame_taps=[lambda f: f.performer == "p0" and ticks_with_p0.append((daemon.ticks, f.index))],
                    model_loader=lambda name: IdentityRestyler())
    vmc_port = sources[1].receiver.address
    receiver = sources[1].receiver
    server = daemon.control
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sender.bind(("127.0.0.1", 0))
    sender.setblocking(False)
    sent_vmc = sent_ctl = 0
    try:
        daemon.start()
        chunk = 48  # then wait until the daemon's threads have read them: no kernel drops
        while sent_vmc < n:
            for d in vmc_junk[sent_vmc:sent_vmc + chunk]:
                sender.sendto(d, vmc_port)
            for d in ctl_junk[sent_ctl:sent_ctl + chunk]:
                sender.sendto(d, server.address)
            sent_vmc = min(n, sent_vmc + chunk)
            sent_ctl = min(n, sent_ctl + chunk)
            assert _wait(lambda: receiver.counters["datagrams"] >= sent_vmc
                         and server.counts["datagrams"] >= sent_ctl), "the daemon stopped reading its ports"
            daemon.step()
            _drain(out_p0, received)
            _drain(out_junk, [])
            _drain(sender, [])  # status replies
        # Still alive and still listening: a real command and a real frame get through.
        frames_before = receiver.counters["frames"]
        accepted_before = server.counts["accepted"]
        sender.sendto(encode_message("/stylecast/intensity", 0.25, "p0"), server.address)
        q = np.tile([0.0, 0.0, 0.0, 1.0], (J, 1))
        for d in encode_frame(np.zeros(3), q, humanoid_skeleton_default().offsets, 0.0):
            sender.sendto(d, vmc_port)
        assert _wait(lambda: receiver.counters["frames"] > frames_before)
        assert _wait(lambda: server.counts["accepted"] > accepted_before)
        for _ in range(5):
            daemon.step()
        _drain(out_p0, received)
        assert daemon.sessions[0].intensity == 0.25
        assert server._thread.is_alive() and receiver._thread.is_alive()
    finally:
        daemon.close()
        for s in (out_p0, out_junk, sender):
            s.close()
    # Exactly what the parsers count in-process for the same bytes: the socket path loses
    # nothing and counts everything by reason.
    reference = VmcParser("junk")
    for d in vmc_junk:
        reference.feed(d, SENDER, 0.0)
    ref_control = ControlServer("127.0.0.1", 0)
    try:
        for d in ctl_junk:
            ref_control.handle(d, ("127.0.0.1", 1))
            ref_control.drain()
    finally:
        ref_control.close()
    live_vmc = {r: receiver.counters[r] for r in VMC_REASONS if receiver.counters[r]}
    assert live_vmc == {r: reference.counters[r] for r in VMC_REASONS if reference.counters[r]}
    assert receiver.counters["datagrams"] == n + 2  # + the two bundles of the final real frame
    live_ctl = {r: server.counts[r] for r in CONTROL_REASONS if server.counts[r]}
    assert live_ctl == {r: ref_control.counts[r] for r in CONTROL_REASONS if ref_control.counts[r]}
    assert server.counts["datagrams"] == n + 1
    print(f"\nlive: VMC port reasons {live_vmc}\ncontrol port reasons {live_ctl}")
    # The legitimate performer: a new frame on every tick, and every one of them arrived.
    indices = [i for _, i in ticks_with_p0]
    assert _contiguous(indices) and len(indices) == daemon.ticks - daemon.settings.delay
    parser = VmcParser("check")
    got = [f for d in received for f in parser.feed(d, SENDER, 0.0)]
    assert len(got) == len(indices)
    times = [f.sender_time for f in got]
    np.testing.assert_allclose(times, [t / 60.0 for t, _ in ticks_with_p0], atol=1e-5)
    assert not {k for k in parser.counters if k in VMC_REASONS}


# ---------------------------------------------------------------------- serial

def _serial_stream(rng, total: int):
    """Random bytes with valid packets, CRC-valid packets the decoder must refuse (role,
    non-finite, non-unit quaternion) and corrupt packets mixed in; returns the stream, the
    valid samples in order and the count of each CRC-valid bad kind."""
    from stylecast.drivers.serial.serial_trackers import BODY, CRC, SYNC, crc32, encode_packet
    from stylecast.drivers.trackers.trackers import TrackerRole, TrackerSample, TrackerStatus

    def raw(role=3, p=(0.0, 0.0, 0.0), q=(0.0, 0.0, 0.0, 1.0), status=1, length=40, version=1):
        body = BODY.pack(7, role, status, 0, *p, *q) + bytes(max(0, length - 40))
        head = bytes((version, length))
        return SYNC + head + body + CRC.pack(crc32(head + body))

    parts, valid, bad = [], [], Counter()
    size = 0
    k = 0
    roles = list(TrackerRole)
    while size < total:
        junk = rng.bytes(int(rng.integers(0, 600)))
        if rng.random() < 0.3:  # junk full of sync markers, the decoder's hardest case
            junk = (SYNC + rng.bytes(int(rng.integers(0, 6)))) * int(rng.integers(1, 30))
        parts.append(junk)
        kind = rng.random()
        if kind < 0.6:
            q = rng.normal(size=4)
            s = TrackerSample(k % 65536, roles[k % len(roles)], k * 1e-3, rng.uniform(-300, 300, 3),
                              q / np.linalg.norm(q), TrackerStatus(int(rng.integers(0, 256))))
            valid.append(s)
            parts.append(encode_packet(s))
            k += 1
        elif kind < 0.7:
            parts.append(raw(role=int(rng.integers(10, 256))))
            bad["role"] += 1
        elif kind < 0.8:
            parts.append(raw(p=(float("nan"), 0.0, float("inf"))))
            bad["value"] += 1
        elif kind < 0.85:
            parts.append(raw(q=(0.0, 0.0, 0.0, 2.0)))
            bad["value"] += 1
        else:  # a valid packet with one flipped byte: the CRC catches it
            pkt = bytearray(encode_packet(TrackerSample(1, TrackerRole.WAIST, 0.0, np.zeros(3),
                                                        np.array([0.0, 0.0, 0.0, 1.0]))))
            pkt[int(rng.integers(4, len(pkt)))] ^= 1 + int(rng.integers(0, 255))
            parts.append(bytes(pkt))
        size += len(parts[-1]) + len(parts[-2])
    return b"".join(parts), valid, bad


def test_serial_decoder_takes_a_mebibyte_of_random_bytes():
    from stylecast.drivers.serial.serial_trackers import PACKET_LEN, FrameDecoder

    rng = np.random.default_rng(11)
    stream, valid, bad = _serial_stream(rng, 1 << 20)
    assert len(stream) >= 1 << 20
    dec = FrameDecoder()
    got = []
    pos = 0
    while pos < len(stream):  # serial reads of any size
        n = int(rng.integers(1, 4096))
        got += dec.feed(stream[pos:pos + n])
        pos += n
    print(f"\nserial fuzz: {len(stream)} bytes, {len(valid)} valid frames, bad by reason {dict(dec.bad_frames)}, "
          f"garbage bytes {dec.garbage_bytes}")
    assert got == valid  # every valid frame, in order, and nothing invented
    assert dec.bad_frames["role"] == bad["role"] and dec.bad_frames["value"] == bad["value"]
    assert dec.bad_frames["crc"] > 0 and dec.bytes_in == len(stream)
    # Every byte is accounted for: in a frame (good or refused whole), skipped, or waiting.
    framed = PACKET_LEN * (len(valid) + bad["role"] + bad["value"])
    assert dec.garbage_bytes + framed + len(dec._buf) == len(stream)


def test_serial_source_over_a_real_pyserial_port_takes_random_bytes():
    from stylecast.drivers.serial.serial_trackers import SerialTrackerSource

    rng = np.random.default_rng(12)
    stream, valid, bad = _serial_stream(rng, 256 << 10)
    src = SerialTrackerSource("loop://")
    try:
        port = src.port
        got = []
        for i in range(0, len(stream), 3000):
            port.write(stream[i:i + 3000])
            got += src.poll()
        for _ in range(5):
            got += src.poll()
        assert got == valid
        assert src.decoder.bad_frames["role"] == bad["role"] and src.connected
        assert src.stats.disconnects == 0
    finally:
        src.close()


# ------------------------------------------------- frames are delivered during a flood

def test_the_receiver_thread_delivers_frames_while_a_flood_keeps_its_socket_full():
    """Under a sustained flood the socket never empties. The receiver thread must still
    hand over the frames it completes every few hundred datagrams, not only once it has
    drained the socket (which, at flood rate, may be never)."""
    from stylecast.drivers.vmc.vmc_in import VmcReceiver

    receiver = VmcReceiver("127.0.0.1", 0, performer_id="p", rcvbuf=1 << 22)
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    junk = [encode_message("/VMC/Ext/Unknown", 1.0)] * 5000  # a flood that is already waiting
    q = np.tile([0.0, 0.0, 0.0, 1.0], (J, 1))
    frame = encode_frame(np.zeros(3), q, humanoid_skeleton_default().offsets, 1.0)
    fed = [0]
    seen_at = []
    feed = receiver.parser.feed

    def counting_feed(*args):
        fed[0] += 1
        if receiver._queue and not seen_at:
            seen_at.append(fed[0])
        return feed(*args)

    receiver.parser.feed = counting_feed
    try:
        for d in frame + junk:
            sender.sendto(d, receiver.address)
        receiver.start()
        assert _wait(lambda: fed[0] >= len(frame) + len(junk), timeout=60)
        frames = receiver.poll()
    finally:
        receiver.close()
        sender.close()
    assert len(frames) == 1
    assert seen_at and seen_at[0] <= 1000, seen_at  # queued long before the 5,000 junk were read
