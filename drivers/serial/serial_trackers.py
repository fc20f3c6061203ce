"""VIVE-style trackers over a serial line: the packet framing, a streaming decoder, and a
non-blocking, self-reconnecting source (and the matching sink the emulator writes with).

The framing is specified for firmware authors in docs/SERIAL_FRAMING.md; in short, one
packet per tracker pose, all fields little-endian::

    A5 5A | ver u8 | len u8 | id u16 | role u8 | status u8 | t_us u64 | px py pz f32 | qx qy qz qw f32 | crc32 u32

The CRC is CRC-32/ISO-HDLC (the zlib/Ethernet CRC, check value 0xCBF43926) over
``ver .. end of body``. A 32-bit CRC rather than a 16-bit one because the decoder re-checks
every sync candidate after garbage: with 5 % corrupted bytes a 16-bit CRC would accept a
false frame every few thousand attempts; a 32-bit one, practically never.
"""

from __future__ import annotations

import logging
import math
import os
import struct
import zlib
from collections import Counter
from dataclasses import dataclass, field
from typing import Callable, Iterable

import numpy as np

from stylecast.motion.clock import RealClock
from stylecast.motion.errors import UserError

from stylecast.drivers.trackers.trackers import TrackerRole, TrackerSample, TrackerStatus

log = logging.getLogger("stylecast.drivers.serial")

SYNC = b"\xa5\x5a"
VERSION = 1
BODY = struct.Struct("<HBBQ3f4f")  # id, role, status, timestamp µs, position, quaternion
BODY_LEN = BODY.size  # 40
MAX_BODY_LEN = 128  # longer bodies are rejected; 40..128 accepted, bytes past 40 ignored
CRC = struct.Struct("<I")
HEADER_LEN = 4  # sync (2) + version (1) + length (1)
PACKET_LEN = HEADER_LEN + BODY_LEN + CRC.size  # 48
DEFAULT_BAUD = 921600
UNIT_QUATERNION_TOLERANCE = 0.01  # |q| must be within 1 % of 1


def crc32(data: bytes) -> int:
    """CRC-32/ISO-HDLC: poly 0x04C11DB7 reflected, init and xorout 0xFFFFFFFF."""
    return zlib.crc32(data) & 0xFFFFFFFF


def encode_packet(sample: TrackerSample) -> bytes:
    """One tracker sample as a framed packet (48 bytes)."""
    t_us = max(0, int(round(sample.timestamp * 1e6)))
    body = BODY.pack(int(sample.tracker_id) & 0xFFFF, int(sample.role), int(sample.status) & 0xFF, t_us,
                     *(float(v) for v in sample.position), *(float(v) for v in sample.orientation))
    head = bytes((VERSION, BODY_LEN))
    return SYNC + head + body + CRC.pack(crc32(head + body))


def encode_packets(samples: Iterable[TrackerSample]) -> bytes:
    return b"".join(encode_packet(s) for s in samples)


class FrameDecoder:
    """Bytes in, samples out, whatever the bytes are.

    ``feed`` accepts any chunking (a packet may arrive split over several reads) and never
    raises. On anything that is not a valid packet it drops the first sync byte only and
    searches again, so a real packet that starts inside a corrupt one is still found.

    ``bad_frames`` counts rejected sync candidates by reason: ``crc`` (checksum mismatch,
    the usual sign of corruption or a torn frame), ``version`` (unknown protocol version),
    ``length`` (body length outside 40..128), ``role`` (checksum fine, unknown role code),
    ``value`` (checksum fine, NaN/inf or a non-unit quaternion). ``garbage_bytes`` counts
    bytes skipped while hunting for a sync marker.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.bad_frames: Counter[str] = Counter()
        self.frames = 0
        self.garbage_bytes = 0
        self.bytes_in = 0

    @property
    def bad_total(self) -> int:
        return sum(self.bad_frames.values())

    def reset(self) -> None:
        """Forget a partial packet (after a reconnect); the counters stay."""
        self.garbage_bytes += len(self._buf)
        self._buf.clear()

    def feed(self, data: bytes) -> list[TrackerSample]:
        self.bytes_in += len(data)
        buf = self._buf
        buf += data
        out: list[TrackerSample] = []
        while True:
            i = buf.find(SYNC)
            if i < 0:
                # Keep a trailing first sync byte: its partner may be in the next read.
                keep = 1 if buf[-1:] == SYNC[:1] else 0
                self.garbage_bytes += len(buf) - keep
                del buf[:len(buf) - keep]
                break
            if i:
                self.garbage_bytes += i
                del buf[:i]
            if len(buf) < HEADER_LEN:
                break
            version, length = buf[2], buf[3]
            if version != VERSION:
                self._reject("version")
                continue
            if not BODY_LEN <= length <= MAX_BODY_LEN:
                self._reject("length")
                continue
            total = HEADER_LEN + length + CRC.size
            if len(buf) < total:
                break  # wait for the rest (a torn frame is caught by its CRC later)
            (crc,) = CRC.unpack_from(buf, HEADER_LEN + length)
            if crc32(bytes(buf[2:HEADER_LEN + length])) != crc:
                self._reject("crc")
                continue
            sample, reason = _parse_body(buf)
            if sample is None:
                self.bad_frames[reason] += 1
                del buf[:total]  # the checksum vouches for the frame boundary: skip it whole
                continue
            self.frames += 1
            out.append(sample)
            del buf[:total]
        return out

    def _reject(self, reason: str) -> None:
        self.bad_frames[reason] += 1
        self.garbage_bytes += 1
        del self._buf[:1]


def _parse_body(buf: bytearray) -> tuple[TrackerSample | None, str]:
    tid, role, status, t_us, px, py, pz, qx, qy, qz, qw = BODY.unpack_from(buf, HEADER_LEN)
    try:
        role = TrackerRole(role)
    except ValueError:
        return None, "role"
    values = (px, py, pz, qx, qy, qz, qw)
    if not all(math.isfinite(v) for v in values):
        return None, "value"
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if abs(norm - 1.0) > UNIT_QUATERNION_TOLERANCE:
        return None, "value"
    return TrackerSample(tid, role, t_us * 1e-6, np.array([px, py, pz]),
                         np.array([qx, qy, qz, qw]) / norm, TrackerStatus(status)), ""


# --------------------------------------------------------------------------------- URLs


def parse_serial_url(url: str) -> tuple[str, dict]:
    """``serial:///dev/ttyUSB0?baud=921600`` -> ("/dev/ttyUSB0", {"baudrate": 921600}), through
    the one URL grammar (``urls.parse_url``: duplicate and unknown options refused); any
    other pyserial URL (``loop://``, ``socket://host:port``, ``spy://...``, ``rfc2217://``)
    or a bare device path is passed to ``serial.serial_for_url`` unchanged."""
    from stylecast.drivers.urls import parse_url

    if not isinstance(url, str) or not url.strip():
        raise UserError("empty serial URL; give a device such as serial:///dev/ttyUSB0?baud=921600")
    url = url.strip()
    if not url.lower().startswith("serial:"):
        return url, {"baudrate": DEFAULT_BAUD}
    parsed = parse_url(url)
    device = serial_device(parsed)
    baud = parsed.take({"baud": (int, DEFAULT_BAUD)})["baud"]
    if baud <= 0:
        raise UserError(f"serial URL {url!r} has baud={baud}; give a positive integer such as baud=921600")
    return device, {"baudrate": baud}


def serial_device(url) -> str:
    """The device of a parsed ``serial://`` URL, as written (``serial:///dev/ttyUSB0``,
    ``serial://COM3``)."""
    device = (url.netloc + url.path) if url.netloc else url.path
    if not device:
        raise UserError(f"serial URL {url.text!r} names no device; write it as serial:///dev/ttyUSB0?baud=921600")
    return device


def _make_port(url: str):
    """An unopened pyserial port for ``url`` (a bad URL raises UserError here, once)."""
    import serial

    device, options = parse_serial_url(url)
    try:
        return serial.serial_for_url(device, do_not_open=True, timeout=0, **options)
    except (ValueError, serial.SerialException) as exc:
        raise UserError(f"cannot use serial URL {url!r} ({exc}); give serial:///dev/DEVICE?baud=N or a "
                        f"pyserial URL such as loop://") from None


@dataclass
class LinkStats:
    opens: int = 0  # successful opens (the first one included)
    open_failures: int = 0  # attempts that failed (device absent, permission, busy)
    disconnects: int = 0  # open links lost (read/write error, device unplugged)
    reconnects: int = 0  # successful opens after a loss
    last_error: str = ""
    extra: dict = field(default_factory=dict)


class _Link:
    """Open / lose / re-open a pyserial port with exponential back-off; never raises."""

    def __init__(self, url: str, clock=None, backoff_initial: float = 0.1, backoff_max: float = 5.0,
                 opener: Callable[[str], object] = _make_port):
        self.url = url
        self.clock = clock or RealClock()
        self.backoff_initial = backoff_initial
        self.backoff_max = backoff_max
        self.stats = LinkStats()
        self._opener = opener
        self._template = opener(url)  # validates the URL now: a bad one is the user's to fix
        self.port = None
        self._backoff = backoff_initial
        self._next_attempt = -math.inf
        self._ever_lost = False
        self._warned = False
        # Open now, so nothing the device sends from here on is flushed by a late open; a
        # failure is the caller's to report (the next attempts warn).
        self.ensure_open(warn=False)

    @property
    def connected(self) -> bool:
        return self.port is not None

    @property
    def next_attempt_in(self) -> float:
        return max(0.0, self._next_attempt - self.clock.now())

    def ensure_open(self, warn: bool = True) -> bool:
        if self.port is not None:
            return True
        now = self.clock.now()
        if now < self._next_attempt:
            return False
        port = self._template if self._template is not None else self._opener(self.url)
        self._template = None
        try:
            port.open()
        except Exception as exc:  # SerialException, OSError, ValueError from exotic URL handlers
            self.stats.open_failures += 1
            self.stats.last_error = str(exc)
            if warn and not self._warned:
                log.warning("serial device %s is not available (%s); retrying with back-off", self.url, exc)
                self._warned = True
            self._schedule_retry(now)
            return False
        self.port = port
        self.stats.opens += 1
        if self._ever_lost:
            self.stats.reconnects += 1
            log.info("serial device %s reconnected", self.url)
        self._backoff = self.backoff_initial
        self._warned = False
        return True

    def lost(self, exc: BaseException) -> None:
        self.stats.disconnects += 1
        self.stats.last_error = str(exc)
        log.warning("serial device %s lost (%s); reconnecting with back-off", self.url, exc)
        self._ever_lost = True
        self._close_port()
        self._schedule_retry(self.clock.now())

    def _schedule_retry(self, now: float) -> None:
        self._next_attempt = now + self._backoff
        self._backoff = min(self._backoff * 2.0, self.backoff_max)

    def _close_port(self) -> None:
        port, self.port = self.port, None
        if port is not None:
            try:
                port.close()
            except Exception:  # closing a vanished device may fail too; nothing to do
                pass

    def close(self) -> None:
        self._close_port()
        self._next_attempt = math.inf


class _OnLink:
    """What a serial source and sink both report about their ``_Link``."""

    link: _Link

    @property
    def stats(self) -> LinkStats:
        return self.link.stats

    @property
    def connected(self) -> bool:
        return self.link.connected


class SerialTrackerSource(_OnLink):
    """Tracker samples from a serial device, pulled with ``poll()`` (non-blocking).

    ``url``: ``serial:///dev/ttyUSB0?baud=921600``, a bare device path, or any pyserial URL
    (``loop://``, ``socket://host:port``, ``spy://...``). A malformed URL raises ``UserError``
    at construction; everything after that (device absent, unplugged, garbage on the line)
    is counted in ``stats`` / ``decoder`` and retried, never raised.
    """

    def __init__(self, url: str, *, clock=None, backoff_initial: float = 0.1, backoff_max: float = 5.0,
                 read_size: int = 4096):
        self.link = _Link(url, clock, backoff_initial, backoff_max)
        self.decoder = FrameDecoder()
        self.read_size = read_size

    @property
    def url(self) -> str:
        return self.link.url

    @property
    def port(self):
        """The open pyserial port, or None while disconnected."""
        self.link.ensure_open()
        return self.link.port

    def poll(self, max_reads: int = 16) -> list[TrackerSample]:
        """Every sample that has arrived since the last call; [] when there is none or the
        device is away (a reconnect is attempted when its back-off has expired)."""
        if not self.link.ensure_open():
            return []
        out: list[TrackerSample] = []
        try:
            for _ in range(max_reads):
                chunk = self.link.port.read(self.read_size)
                if not chunk:
                    break
                out += self.decoder.feed(chunk)
                if len(chunk) < self.read_size:
                    break
        except Exception as exc:  # SerialException / OSError: the device went away
            self.link.lost(exc)
            self.decoder.reset()
        return out

    def close(self) -> None:
        self.link.close()

    def __enter__(self) -> "SerialTrackerSource":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class SerialTrackerSink(_OnLink):
    """Writes framed samples to a serial device without ever blocking the caller.

    Bytes the device cannot take yet wait in a bounded buffer; past ``max_pending`` the
    oldest are dropped (``stats.extra["dropped_bytes"]``), which the receiver sees as a torn
    frame and resynchronises after. Lost devices are re-opened with back-off.
    """

    def __init__(self, url: str | None = None, *, port=None, clock=None, backoff_initial: float = 0.1,
                 backoff_max: float = 5.0, max_pending: int = 65536):
        if port is not None:  # an already open port (e.g. the other end of a loop:// test)
            self.link = _Link("<port>", clock, backoff_initial, backoff_max, opener=lambda _u: None)
            self.link.port = port
            self.link.stats.opens = 1
        else:
            self.link = _Link(url, clock, backoff_initial, backoff_max)
        self.max_pending = max_pending
        self._pending = bytearray()
        self.packets = 0
        self.link.stats.extra["dropped_bytes"] = 0

    def send(self, samples: Iterable[TrackerSample]) -> None:
        samples = list(samples)
        data = encode_packets(samples)
        self.packets += len(samples)
        self._pending += data
        self.flush()
        overflow = len(self._pending) - self.max_pending
        if overflow > 0:
            del self._pending[:overflow]
            self.link.stats.extra["dropped_bytes"] += overflow

    def flush(self) -> None:
        if not self._pending or not self.link.ensure_open():
            return
        port = self.link.port
        try:
            n = _write_nonblocking(port, bytes(self._pending))
            del self._pending[:n]
        except Exception as exc:
            self.link.lost(exc)

    def close(self) -> None:
        self.link.close()


def _write_nonblocking(port, data: bytes) -> int:
    """Write what the device takes now; return how many bytes that was.

    pyserial's posix ``write`` either blocks until everything is out or, with a zero write
    timeout, spins on EAGAIN; a device file written directly (pyserial opens it
    O_NONBLOCK) just takes what fits. Ports without a file descriptor (loop://, socket://)
    buffer internally and take everything.
    """
    try:
        fd = port.fileno()
    except Exception:
        n = port.write(data)
        return len(data) if n is None else int(n)
    try:
        return os.write(fd, data)
    except BlockingIOError:
        return 0


# ------------------------------------------------------------------ the daemon's serial:// source

def open_source(url, performer: str):
    """The daemon's ``serial://`` factory (``drivers.sources``):
    ``serial:///dev/ttyUSB0?baud=921600&points=10&calibrate=1&blend=0.3``."""
    from stylecast.drivers.trackers.solver import TRACKER_OPTIONS, solved_source

    opts = url.take({"baud": (int, DEFAULT_BAUD), **TRACKER_OPTIONS})
    trackers = SerialTrackerSource(f"serial://{serial_device(url)}?baud={opts['baud']}")
    return solved_source(url, trackers, performer, opts)
