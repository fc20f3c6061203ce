"""The serial tracker framing, the streaming decoder, the pyserial source and sink."""

from __future__ import annotations

import math
import os
import struct
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from stylecast.drivers.serial.serial_trackers import (BODY, CRC, PACKET_LEN, SYNC, FrameDecoder, SerialTrackerSink,
                                               SerialTrackerSource, crc32, encode_packet, encode_packets,
                                               parse_serial_url)
from stylecast.drivers.trackers.trackers import FrameAssembler, TrackerRole, TrackerSample, TrackerStatus
from stylecast.motion.errors import UserError

# The example of docs/SERIAL_FRAMING.md, byte for byte.
DOC_EXAMPLE = bytes.fromhex(
    "A55A0128030008 0160E31600000000 00000048410000 0041 0000F2C1 00000000"
    "9A99193F 00000000 CDCC4C3F 19ABDCE8".replace(" ", ""))


class FakeClock:
    def __init__(self, t: float = 0.0):
        self.t = t

    def now(self) -> float:
        return self.t

    def sleep(self, dt: float) -> None:
        self.t += max(dt, 0.0)


def sample(i: int = 0, role: TrackerRole = TrackerRole.WAIST, t: float | None = None,
           status=TrackerStatus.TRACKING_VALID) -> TrackerSample:
    rng = np.random.default_rng(i)
    q = rng.normal(size=4)
    return TrackerSample(i % 65536, role, i / 90 if t is None else t, rng.uniform(-200, 200, 3), q / np.linalg.norm(q),
                         status)


def samples(n: int) -> list[TrackerSample]:
    roles = list(TrackerRole)
    return [sample(i, roles[i % len(roles)]) for i in range(n)]


def raw_packet(version=1, length=40, tid=1, role=3, status=1, t_us=0, p=(0, 0, 0), q=(0, 0, 0, 1), crc=None):
    body = BODY.pack(tid, role, status, t_us, *p, *q) + bytes(max(0, length - 40))
    head = bytes((version, length))
    c = crc32(head + body) if crc is None else crc
    return SYNC + head + body + CRC.pack(c)


# ----------------------------------------------------------------------------- framing

def test_crc_is_crc32_iso_hdlc_known_answer():
    assert crc32(b"123456789") == 0xCBF43926
    assert crc32(b"") == 0


def test_documented_example_packet_byte_for_byte():
    s = TrackerSample(3, TrackerRole.LEFT_FOOT, 1.5, np.array([12.5, 8.0, -30.25]), np.array([0.0, 0.6, 0.0, 0.8]))
    assert len(DOC_EXAMPLE) == PACKET_LEN == 48
    assert encode_packet(s) == DOC_EXAMPLE
    assert struct.unpack_from("<I", DOC_EXAMPLE, 44)[0] == crc32(DOC_EXAMPLE[2:44]) == 0xE8DCAB19
    (decoded,) = FrameDecoder().feed(DOC_EXAMPLE)
    assert decoded == s and decoded.valid


def test_round_trip_many_samples_any_chunking():
    sent = samples(300) + [sample(7, status=TrackerStatus.NONE), sample(8, status=TrackerStatus(0x0F))]
    data = encode_packets(sent)
    for chunk in (1, 7, 48, 1000, len(data)):
        dec = FrameDecoder()
        got = []
        for i in range(0, len(data), chunk):
            got += dec.feed(data[i:i + chunk])
        assert got == sent
        assert dec.bad_total == 0 and dec.garbage_bytes == 0
    assert not got[-2].valid and got[-1].status & TrackerStatus.BUTTON


def test_resynchronises_after_garbage_including_false_sync_markers():
    rng = np.random.default_rng(1)
    sent = samples(50)
    stream = bytearray()
    for s in sent:
        junk = bytearray(rng.integers(0, 256, rng.integers(0, 40)).astype(np.uint8).tobytes())
        if rng.random() < 0.5:
            junk += SYNC + bytes([1, 40]) + bytes(10)  # a plausible header that is not a packet
        stream += junk + encode_packet(s)
    dec = FrameDecoder()
    got = []
    for i in range(0, len(stream), 33):
        got += dec.feed(bytes(stream[i:i + 33]))
    assert got == sent
    assert dec.garbage_bytes > 0


def test_torn_frame_costs_only_itself():
    a, b, c = samples(3)
    stream = encode_packet(a) + encode_packet(b)[:30] + encode_packet(c)
    dec = FrameDecoder()
    assert dec.feed(stream) == [a, c]
    assert dec.bad_frames["crc"] >= 1


def test_bad_frames_counted_by_reason():
    good = encode_packet(sample(1))
    stream = (raw_packet(version=2) + raw_packet(length=12) + raw_packet(role=42)
              + raw_packet(p=(math.nan, 0, 0)) + raw_packet(q=(0, 0, 0, 2)) + raw_packet(crc=1234) + good)
    dec = FrameDecoder()
    assert dec.feed(stream) == [sample(1)]
    assert {k: v for k, v in dec.bad_frames.items()} == {"version": 1, "length": 1, "role": 1, "value": 2, "crc": 1}


def test_longer_body_of_a_future_version_is_read_and_extra_bytes_ignored():
    pkt = raw_packet(length=52, tid=9, role=int(TrackerRole.HMD), t_us=2_000_000)
    (s,) = FrameDecoder().feed(pkt)
    assert (s.tracker_id, s.role, s.timestamp) == (9, TrackerRole.HMD, 2.0)


def test_five_percent_corrupted_bytes_every_intact_frame_recovered():
    rng = np.random.default_rng(5)
    sent = samples(3000)
    data = bytearray(encode_packets(sent))
    hit = rng.random(len(data)) < 0.05
    noise = rng.integers(1, 256, len(data)).astype(np.uint8)
    corrupted = np.frombuffer(bytes(data), np.uint8).copy()
    corrupted[hit] ^= noise[hit]  # xor with non-zero: every hit byte really changes
    intact = [s for i, s in enumerate(sent) if not hit[i * PACKET_LEN:(i + 1) * PACKET_LEN].any()]
    dec = FrameDecoder()
    got = []
    stream = corrupted.tobytes()
    pos = 0
    while pos < len(stream):  # random read sizes, as a serial port delivers them
        n = int(rng.integers(1, 200))
        got += dec.feed(stream[pos:pos + n])
        pos += n
    keys = {(s.tracker_id, round(s.timestamp * 1e6)) for s in got}
    missing = [s for s in intact if (s.tracker_id, round(s.timestamp * 1e6)) not in keys]
    assert not missing
    # Nothing invented: every decoded sample is one that was sent, intact.
    by_key = {(s.tracker_id, round(s.timestamp * 1e6)): s for s in sent}
    assert all(by_key.get((s.tracker_id, round(s.timestamp * 1e6))) == s for s in got)
    assert len(got) == len(intact)
    assert dec.bad_frames["crc"] > 0.5 * (len(sent) - len(intact))
    assert 0.05 < 1 - len(intact) / len(sent) < 0.99  # the corruption really hit most frames


# ----------------------------------------------------------------------------- URLs

def test_serial_url_parsing():
    assert parse_serial_url("serial:///dev/ttyUSB0?baud=921600") == ("/dev/ttyUSB0", {"baudrate": 921600})
    assert parse_serial_url("serial:///dev/ttyACM1") == ("/dev/ttyACM1", {"baudrate": 921600})
    assert parse_serial_url("serial://COM3?baud=115200") == ("COM3", {"baudrate": 115200})
    assert parse_serial_url("loop://") == ("loop://", {"baudrate": 921600})
    assert parse_serial_url("/dev/ttyUSB1")[0] == "/dev/ttyUSB1"


@pytest.mark.parametrize("url", ["", "serial://", "serial:///dev/ttyUSB0?baud=fast",
                                 "serial:///dev/ttyUSB0?baud=-3", "serial:///dev/ttyUSB0?parity=E"])
def test_bad_serial_urls_are_user_errors(url):
    with pytest.raises(UserError) as err:
        parse_serial_url(url)
    assert "serial" in str(err.value)


def test_unknown_pyserial_protocol_is_a_user_error():
    with pytest.raises(UserError):
        SerialTrackerSource("nosuchproto://x")


# ----------------------------------------------------------------------------- loop://

def test_loop_url_end_to_end():
    src = SerialTrackerSource("loop://")
    sink = SerialTrackerSink(port=src.port)
    sent = samples(40)
    for i in range(0, 40, 10):
        sink.send(sent[i:i + 10])
    got = []
    for _ in range(10):
        got += src.poll()
    assert got == sent
    assert src.decoder.bad_total == 0


# ----------------------------------------------------------------------------- real ptys

def _raw_master(fd: int) -> None:
    import termios
    import tty

    tty.setraw(fd, termios.TCSANOW)
    os.set_blocking(fd, False)


def _read_all(fd: int, deadline: float, want: int) -> bytes:
    out = bytearray()
    while time.monotonic() < deadline and len(out) < want:
        try:
            chunk = os.read(fd, 65536)
        except BlockingIOError:
            time.sleep(0.002)
            continue
        out += chunk
    return bytes(out)


def test_pty_sink_writes_slave_path_driver_decodes_master():
    master, slave = os.openpty()
    try:
        _raw_master(master)
        path = os.ttyname(slave)
        sink = SerialTrackerSink(f"serial://{path}?baud=921600")
        sent = samples(200)
        for i in range(0, len(sent), 10):
            sink.send(sent[i:i + 10])
            sink.flush()
        data = _read_all(master, time.monotonic() + 5, len(sent) * PACKET_LEN)
        assert FrameDecoder().feed(data) == sent
        sink.close()
    finally:
        os.close(master)
        os.close(slave)


def test_pty_source_reads_slave_path():
    master, slave = os.openpty()
    try:
        _raw_master(master)
        src = SerialTrackerSource(f"serial://{os.ttyname(slave)}?baud=921600")
        sent = samples(100)
        os.write(master, encode_packets(sent))
        got = []
        deadline = time.monotonic() + 5
        while len(got) < len(sent) and time.monotonic() < deadline:
            got += src.poll()
            time.sleep(0.001)
        assert got == sent
        assert src.connected and src.stats.opens == 1
        src.close()
    finally:
        os.close(master)
        os.close(slave)


def test_device_disappears_and_returns_reconnect_with_backoff():
    clock = FakeClock(100.0)
    with tempfile.TemporaryDirectory() as tmp:
        link = Path(tmp) / "tracker0"  # like /dev/serial/by-id/...: a stable name for a changing node
        m1, s1 = os.openpty()
        _raw_master(m1)
        link.symlink_to(os.ttyname(s1))
        src = SerialTrackerSource(f"serial://{link}?baud=921600", clock=clock, backoff_initial=0.1, backoff_max=0.8)
        os.write(m1, encode_packets(samples(5)))
        got = []
        for _ in range(200):
            got += src.poll()
            if len(got) == 5:
                break
            time.sleep(0.002)
        assert len(got) == 5
        # Unplug: the pty vanishes; the driver notices on its next read.
        os.close(m1)
        os.close(s1)
        link.unlink()
        link.symlink_to(Path(tmp) / "absent")
        assert src.poll() == []
        assert src.stats.disconnects == 1 and not src.connected
        # Back-off: attempts at +0.1, then +0.2, +0.4, +0.8, +0.8 ... never in between.
        attempts = []
        for step in range(400):
            clock.t += 0.01
            before = src.stats.open_failures
            assert src.poll() == []
            if src.stats.open_failures > before:
                attempts.append(round(clock.t - 100.0, 2))
        gaps = np.diff(attempts)
        assert list(np.round(gaps[:3], 2)) == [0.2, 0.4, 0.8] and np.allclose(gaps[3:], 0.8, atol=0.011)
        # Plug back in (a new pty behind the same name): reconnects at the next attempt.
        m2, s2 = os.openpty()
        try:
            _raw_master(m2)
            link.unlink()
            link.symlink_to(os.ttyname(s2))
            more = samples(8)[3:]
            got = []
            for _ in range(200):
                clock.t += 0.05
                got += src.poll()
                if src.connected and not got:
                    os.write(m2, encode_packets(more))
                    time.sleep(0.01)
                if len(got) == len(more):
                    break
            assert got == more
            assert src.stats.reconnects == 1 and src.stats.disconnects == 1
            src.close()
        finally:
            os.close(m2)
            os.close(s2)


def test_sink_never_blocks_when_nobody_reads():
    master, slave = os.openpty()
    try:
        sink = SerialTrackerSink(f"serial://{os.ttyname(slave)}", max_pending=4096)
        batch = samples(10)
        start = time.monotonic()
        for _ in range(2000):  # ~1 MB: far more than a pty buffers
            sink.send(batch)
        assert time.monotonic() - start < 10
        assert sink.stats.extra["dropped_bytes"] > 0
        sink.close()
    finally:
        os.close(master)
        os.close(slave)


def test_frame_assembler_groups_by_timestamp_and_drops_late_samples():
    asm = FrameAssembler()
    a = [sample(i, r, t=1.0) for i, r in enumerate([TrackerRole.HMD, TrackerRole.WAIST])]
    b = [sample(5, TrackerRole.HMD, t=1.01)]
    frames = asm.feed(a + b + [sample(6, TrackerRole.LEFT_FOOT, t=0.99)])
    assert len(frames) == 1 and frames[0].timestamp == 1.0
    assert frames[0].valid[TrackerRole.HMD] and frames[0].valid[TrackerRole.WAIST]
    assert not frames[0].valid[TrackerRole.LEFT_FOOT]
    assert asm.late_samples == 1
    last = asm.flush()
    assert last.timestamp == 1.01 and asm.flush() is None
