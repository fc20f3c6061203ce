"""VMC performer output: encode humanoid frames as VMC/OSC and fan them out over UDP.

Per frame, in this order (the order matters to receivers that frame unbundled streams):

    /VMC/Ext/Root/Pos  s "root"   fff position  ffff rotation
    /VMC/Ext/Bone/Pos  s <bone>   fff local position  ffff local rotation   (x 22, HUMANOID_BONES)
    /VMC/Ext/OK        i loaded  i calibState  i calibMode  i trackingStatus
    /VMC/Ext/T         f time    (last: it marks the end of the frame, see vmc_parse)

All in Unity space (left-handed, Y up, metres) via ``motion.unity``.

Root and Hips (decided from the VMC marionette spec and what VirtualMotionCapture and
the protocol's reference sender send): /VMC/Ext/Root/Pos is the pose of the *avatar's
root object* (the GameObject above the skeleton), and /VMC/Ext/Bone/Pos carries every
bone's ``Transform.localPosition``/``localRotation``, the Hips included, so the Hips'
local pose is relative to that root. Receivers compose them: EVMC4U writes Root/Pos to
the model root and each Bone/Pos to the bone's local transform; VRM4U ignores Root/Pos
altogether. Sending the hips' world pose in *both* messages would double it (an avatar
at twice the hip height, its turn applied twice), and sending it only in Root/Pos would
freeze the avatar in place and facing in every receiver that ignores the root. So the
default ``root_mode="origin"`` sends Root/Pos as the identity at the origin and puts the
hips' world position and rotation in the Hips bone (its local pose relative to an
identity root); every other bone's local position is its offset from its parent, in
metres, so receivers that apply bone positions keep the performer's proportions.
``root_mode="hips"`` is the alternative for receivers that want motion on the root:
Root/Pos carries the hips' world pose and the Hips bone is identity at zero.

Encoding is the hot path of the daemon (every performer, every sink, 60 times a second).
Hand-written because measured hot: python-osc's builder takes about 0.5 ms per frame.
Here each frame layout (bundle headers, element sizes, addresses, type tags, bone
names, the OK integers) is laid out once as bytes; per frame only the float slots are
written, all at once, through a big-endian float32 view of that template (numpy), then
the datagrams are sliced out. tests/test_vmc_out.py checks the bytes equal python-osc's
builder output for the same content and decode identically with python-osc's parser.
"""

from __future__ import annotations

import errno
import ipaddress
import socket
import sys
from collections import Counter
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import HUMANOID_BONES
from stylecast.motion.unity import position_to_unity, rotation_to_unity

from stylecast.drivers.vmc.osc_packets import (DEFAULT_MAX_DATAGRAM, IMMEDIATE, check_port, encode_message,
                          group_for_bundles, osc_string, pack_datagrams)
from stylecast.drivers.urls import parse_vmc_url

if TYPE_CHECKING:
    from stylecast.drivers.trackers.trackers import TrackerSample

ROOT_ADDRESS = "/VMC/Ext/Root/Pos"
BONE_ADDRESS = "/VMC/Ext/Bone/Pos"
OK_ADDRESS = "/VMC/Ext/OK"
TIME_ADDRESS = "/VMC/Ext/T"
TRACKER_ADDRESS = {"hmd": "/VMC/Ext/Hmd/Pos", "con": "/VMC/Ext/Con/Pos", "tra": "/VMC/Ext/Tra/Pos"}
# loaded=1, calibState=3 (calibrated), calibMode=0 (normal), trackingStatus=1 (tracking).
# calibState matters: EVMC4U can hide the avatar while it is not 3.
DEFAULT_OK = (1, 3, 0, 1)
ROOT_MODES = ("origin", "hips")
_IDENTITY_ROOT = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
_BIG_F32 = np.dtype(">f4")
_LIMIT = 1e30  # finite and far inside float32 range: anything else is a bug upstream
_LIMIT_SQ = _LIMIT * _LIMIT


class FrameEncoder:
    """Encodes frames of one fixed layout (bundled or not, datagram limit, OK flags).

    Not thread-safe: it reuses one template buffer (each sink thread owns an encoder).
    """

    def __init__(self, bundled: bool = True, max_datagram: int = DEFAULT_MAX_DATAGRAM,
                 root_mode: str = "origin", ok: Sequence[int] = DEFAULT_OK) -> None:
        if root_mode not in ROOT_MODES:
            raise ValueError(f"root_mode must be one of {ROOT_MODES}, got {root_mode!r}")
        self.bundled, self.max_datagram, self.root_mode = bundled, max_datagram, root_mode
        pose_prefix = osc_string(",sfffffff")
        # (bytes with the float slots zeroed, number of float slots at its end)
        messages = [(osc_string(ROOT_ADDRESS) + pose_prefix + osc_string("root"), 7)]
        messages += [(osc_string(BONE_ADDRESS) + pose_prefix + osc_string(b), 7) for b in HUMANOID_BONES]
        messages.append((encode_message(OK_ADDRESS, *[int(v) for v in ok]), 0))
        messages.append((osc_string(TIME_ADDRESS) + osc_string(",f"), 1))
        sizes = [len(p) + 4 * n for p, n in messages]
        groups = group_for_bundles(sizes, max_datagram) if bundled else [[i] for i in range(len(messages))]

        template = bytearray()
        slots: list[int] = []  # float32 index into the template of each value, in value order
        slot_of_message: dict[int, list[int]] = {}
        self._spans: list[tuple[int, int]] = []
        for group in groups:
            start = len(template)
            if bundled:
                template += b"#bundle\x00" + IMMEDIATE.to_bytes(8, "big")
            for i in group:
                prefix, n = messages[i]
                if bundled:
                    template += sizes[i].to_bytes(4, "big", signed=True)
                template += prefix
                first = len(template) // 4
                slot_of_message[i] = list(range(first, first + n))
                template += bytes(4 * n)
            self._spans.append((start, len(template)))
        for i in range(len(messages)):
            slots += slot_of_message[i]
        self._template = template
        # Writable view of the template as raw 32-bit words: the values are cast to
        # big-endian float32 once, then scattered bit-for-bit (faster than a scatter
        # into a big-endian float view, which byte-swaps element by element).
        self._words = np.frombuffer(self._template, dtype=np.uint32)
        self._slots = np.asarray(slots, dtype=np.intp)

    @property
    def datagrams_per_frame(self) -> int:
        return len(self._spans)

    def encode(self, root_position: np.ndarray, rotations: np.ndarray, bone_offsets: np.ndarray,
               time: float) -> list[bytes]:
        """One frame (internal space: cm, xyzw) -> its datagrams. ValueError on non-finite
        or absurd input, which would otherwise reach every receiver as NaN."""
        values = frame_values(np.asarray(root_position)[None], np.asarray(rotations)[None],
                              np.asarray(bone_offsets)[None], time, self.root_mode)
        if not sendable(values)[0]:
            raise ValueError("VMC frame has non-finite or out-of-range values; not sent")
        return self.write(values.astype(_BIG_F32).view(np.uint32)[0])

    def write(self, words: np.ndarray) -> list[bytes]:
        """One frame's values as big-endian float32 bit patterns (``frame_values`` order,
        viewed as uint32) -> its datagrams: the values scattered bit for bit into the
        template (faster than a scatter into a big-endian float view, which byte-swaps
        element by element), the datagrams sliced out."""
        self._words[self._slots] = words
        mv = memoryview(self._template)
        return [bytes(mv[a:b]) for a, b in self._spans]


def frame_values(roots: np.ndarray, rotations: np.ndarray, bone_offsets: np.ndarray, time: float,
                 root_mode: str = "origin") -> np.ndarray:
    """The float slots of frames (P,) in a ``FrameEncoder``'s value order, Unity space: the
    root's pose, each bone's local position and rotation, then the time (P, 23 * 7 + 1).
    Frames of many performers in one pass (the daemon's tick); see the module docstring
    for the root and the Hips."""
    p, joints = rotations.shape[:2]
    values = np.empty((p, (1 + joints) * 7 + 1))
    pose = values[:, :-1].reshape(p, 1 + joints, 7)  # root row, bone rows
    pose[:, 1:, :3] = position_to_unity(bone_offsets)
    pose[:, 1:, 3:] = rotation_to_unity(rotations)
    hips = position_to_unity(roots)
    if root_mode == "origin":
        pose[:, 0] = _IDENTITY_ROOT
        pose[:, 1, :3] = hips
    else:
        pose[:, 0, :3] = hips
        pose[:, 0, 3:] = pose[:, 1, 3:]
        pose[:, 1] = _IDENTITY_ROOT
    values[:, -1] = time
    return values


def sendable(values: np.ndarray) -> np.ndarray:
    """Which frames' values (P, S) may go out: one dot product per frame checks every
    value (NaN and inf propagate, huge values overflow)."""
    return np.einsum("ij,ij->i", values, values) < _LIMIT_SQ


_default_encoders: dict[tuple, FrameEncoder] = {}


def encode_frame(root_position: np.ndarray, rotations: np.ndarray, bone_offsets: np.ndarray,
                 time: float, bundled: bool = True, max_datagram: int = DEFAULT_MAX_DATAGRAM,
                 root_mode: str = "origin") -> list[bytes]:
    """Datagrams of one VMC frame. ``root_position`` (3,) cm: the hips' world position;
    ``rotations`` (22, 4) local quaternions xyzw of HUMANOID_BONES (the Hips' is its world
    rotation); ``bone_offsets`` (22, 3) cm: each bone's offset from its parent (row 0
    unused: the Hips sit at ``root_position``); ``time`` seconds for /VMC/Ext/T.
    Not thread-safe (shares one encoder per layout); threads should own a FrameEncoder."""
    key = (bundled, max_datagram, root_mode)
    enc = _default_encoders.get(key)
    if enc is None:
        enc = _default_encoders[key] = FrameEncoder(bundled, max_datagram, root_mode)
    return enc.encode(root_position, rotations, bone_offsets, time)


def encode_frame_reference(root_position: np.ndarray, rotations: np.ndarray, bone_offsets: np.ndarray,
                           time: float, bundled: bool = True, max_datagram: int = DEFAULT_MAX_DATAGRAM,
                           root_mode: str = "origin", ok: Sequence[int] = DEFAULT_OK) -> list[bytes]:
    """The same frame built with python-osc's builders: the slow reference that tests
    compare the fast path against and the bench measures."""
    from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
    from pythonosc.osc_message_builder import OscMessageBuilder

    def message(address: str, *args) -> object:
        b = OscMessageBuilder(address)
        for a in args:
            b.add_arg(a)
        return b.build()

    offsets = position_to_unity(bone_offsets)
    rots = rotation_to_unity(rotations)
    hips = position_to_unity(root_position)
    root = list(_IDENTITY_ROOT)
    if root_mode == "hips":
        root = [*hips, *rots[0]]
        offsets[0], rots[0] = 0.0, (0.0, 0.0, 0.0, 1.0)
    else:
        offsets[0] = hips
    msgs = [message(ROOT_ADDRESS, "root", *map(float, root))]
    msgs += [message(BONE_ADDRESS, b, *map(float, offsets[j]), *map(float, rots[j]))
             for j, b in enumerate(HUMANOID_BONES)]
    msgs += [message(OK_ADDRESS, *map(int, ok)), message(TIME_ADDRESS, float(time))]
    if not bundled:
        return [m.dgram for m in msgs]
    out = []
    for group in group_for_bundles([m.size for m in msgs], max_datagram):
        bb = OscBundleBuilder(IMMEDIATELY)  # python-osc's 0 is written as the time tag 1
        for i in group:
            bb.add_content(msgs[i])
        out.append(bb.build().dgram)
    return out


def encode_trackers(trackers: Iterable, time: float | None = None, bundled: bool = True,
                    max_datagram: int = DEFAULT_MAX_DATAGRAM) -> list[bytes]:
    """Tracker poses (``vmc_parse.TrackerSample``-like: kind "hmd"/"con"/"tra", serial,
    position cm and rotation xyzw in internal space, local flag) as /VMC/Ext/{Hmd,Con,Tra}/Pos
    (or their /Local variants), then /VMC/Ext/T if ``time`` is given. Cold path (the
    tracker emulator): a handful of messages per frame needs no template."""
    msgs = []
    for t in trackers:
        p = position_to_unity(t.position)
        q = rotation_to_unity(t.rotation)
        values = np.concatenate([p, q])
        if not np.all(np.abs(values) < _LIMIT):
            raise ValueError(f"tracker {t.serial!r} has non-finite values; not sent")
        address = TRACKER_ADDRESS[t.kind] + ("/Local" if t.local else "")
        msgs.append(encode_message(address, str(t.serial), *map(float, values)))
    if time is not None:
        msgs.append(encode_message(TIME_ADDRESS, float(time)))
    return pack_datagrams(msgs, bundled, max_datagram)


def _resolve(host: str, port: int) -> tuple[int, tuple]:
    check_port(port, "VMC output")
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
    except (socket.gaierror, UnicodeError):
        raise UserError(f"cannot resolve VMC output host {host!r}; give an IP address or a "
                        f"known host name, as in vmc://127.0.0.1:{port}") from None
    infos.sort(key=lambda i: i[0] != socket.AF_INET)  # prefer IPv4 where both exist
    family, _, _, _, sockaddr = infos[0]
    return family, sockaddr


class VmcSender:
    """Send-only UDP fan-out to several VMC receivers (marionettes, the viewer).

    One socket per address family in use (normally exactly one, IPv4), non-blocking so a
    full send buffer drops a datagram (counted) instead of stalling the output clock.
    Nothing is bound until the first send, and then only an ephemeral port.

    A receiver that vanishes: on Linux an unconnected UDP socket ignores ICMP "port
    unreachable" unless IP_RECVERR is set, in which case the error surfaces on the
    *next* sendto, whatever its destination, and that datagram is lost. We set
    IP_RECVERR to learn which receiver went away, and on such an error read the socket's
    error queue, which names the original destination of each failed datagram, count it
    against that target, and retry the send that was refused on its behalf. A dead
    receiver therefore never costs a live one a datagram.
    """

    def __init__(self, targets: Sequence[tuple[str, int]], bundled: bool = True,
                 max_datagram: int = DEFAULT_MAX_DATAGRAM, root_mode: str = "origin",
                 ok: Sequence[int] = DEFAULT_OK) -> None:
        if not targets:
            raise UserError("no VMC output given; add one such as --out vmc://127.0.0.1:39539")
        self.targets = [(str(h), p) for h, p in targets]
        self._resolved = [_resolve(h, p) for h, p in self.targets]
        self._by_sockaddr = {sa[:2]: i for i, (_, sa) in enumerate(self._resolved)}
        self.encoder = FrameEncoder(bundled, max_datagram, root_mode, ok)
        self._sockets: dict[int, socket.socket] = {}
        self.datagrams_sent = 0
        self.bytes_sent = 0
        self.frames_sent = 0
        self.frames_rejected = 0  # non-finite frames refused before encoding
        self.sent = [0] * len(self.targets)  # datagrams per target
        self.errors = [Counter() for _ in self.targets]  # reason -> count, per target

    @classmethod
    def from_urls(cls, urls: Sequence[str], **kwargs) -> "VmcSender":
        """``vmc://HOST:PORT[?bundled=0|1]`` each; options must agree across URLs."""
        targets, bundled = [], kwargs.pop("bundled", True)
        for url in urls:
            host, port, opts = parse_vmc_url(url, allowed_options=("bundled",))
            if port == 0:
                raise UserError(f"VMC output {url!r} has port 0; give the receiver's port, "
                                f"as in vmc://{host}:39539")
            if "bundled" in opts:
                if opts["bundled"] not in ("0", "1"):
                    raise UserError(f"VMC output {url!r}: bundled must be 0 or 1")
                bundled = opts["bundled"] == "1"
            targets.append((host, port))
        return cls(targets, bundled=bundled, **kwargs)

    def _socket(self, family: int) -> socket.socket:
        sock = self._sockets.get(family)
        if sock is None:
            sock = socket.socket(family, socket.SOCK_DGRAM)
            sock.setblocking(False)
            # Hardening: the kernel binds a send-only socket to every interface (0.0.0.0)
            # on its first send, where anyone on the network can reach it. When every
            # receiver of this family is on this machine, bind it to loopback instead.
            hosts = [sa[0] for fam, sa in self._resolved if fam == family]
            if hosts and all(ipaddress.ip_address(h.split("%")[0]).is_loopback for h in hosts):
                try:
                    sock.bind(("127.0.0.1", 0) if family == socket.AF_INET else ("::1", 0))
                except OSError:
                    pass  # no loopback address of this family: keep the kernel's choice
            if sys.platform.startswith("linux"):
                level, opt = ((socket.IPPROTO_IP, 11) if family == socket.AF_INET
                              else (socket.IPPROTO_IPV6, 25))  # IP_RECVERR / IPV6_RECVERR
                try:
                    sock.setsockopt(level, opt, 1)
                except OSError:
                    pass
            self._sockets[family] = sock
        return sock

    def _drain_error_queue(self, sock: socket.socket) -> None:
        flags = getattr(socket, "MSG_ERRQUEUE", 0)
        if not flags:
            return
        for _ in range(1024):  # bounded: the queue is bounded by the receive buffer anyway
            try:
                _, _, _, addr = sock.recvmsg(1, 512, flags | socket.MSG_DONTWAIT)
            except OSError:
                return
            i = self._by_sockaddr.get(addr[:2]) if addr else None
            if i is not None:
                self.errors[i]["unreachable"] += 1

    def _send_one(self, i: int, datagram: bytes) -> bool:
        family, sockaddr = self._resolved[i]
        sock = self._socket(family)
        for attempt in (0, 1):
            try:
                sock.sendto(datagram, sockaddr)
            except BlockingIOError:
                self.errors[i]["would_block"] += 1
                return False
            except ConnectionRefusedError:
                # A pending ICMP error of some earlier datagram: attribute it, then retry.
                self._drain_error_queue(sock)
                if attempt == 0:
                    continue
                self.errors[i]["refused"] += 1
                return False
            except OSError as exc:
                self.errors[i][errno.errorcode.get(exc.errno or 0, "oserror").lower()] += 1
                return False
            self.sent[i] += 1
            self.datagrams_sent += 1
            self.bytes_sent += len(datagram)
            return True
        return False

    def send_datagrams(self, datagrams: Sequence[bytes]) -> int:
        """Send each datagram to every target; returns how many sendto calls succeeded."""
        ok = 0
        for i in range(len(self._resolved)):
            for d in datagrams:
                ok += self._send_one(i, d)
        return ok

    def send_frame(self, root_position: np.ndarray, rotations: np.ndarray, bone_offsets: np.ndarray,
                   time: float) -> int:
        """Encode and fan out one frame (see ``encode_frame``); never raises on a bad
        frame or a bad network: both are counted."""
        try:
            datagrams = self.encoder.encode(root_position, rotations, bone_offsets, time)
        except ValueError:
            self.frames_rejected += 1
            return 0
        self.frames_sent += 1
        return self.send_datagrams(datagrams)

    def counters(self) -> dict:
        """A snapshot: totals and, per "host:port" target, datagrams sent and errors by reason."""
        return {
            "frames_sent": self.frames_sent, "frames_rejected": self.frames_rejected,
            "datagrams_sent": self.datagrams_sent, "bytes_sent": self.bytes_sent,
            "targets": {f"{h}:{p}": {"sent": self.sent[i], "errors": dict(self.errors[i])}
                        for i, (h, p) in enumerate(self.targets)},
        }

    def close(self) -> None:
        for sock in self._sockets.values():
            sock.close()
        self._sockets.clear()

    def __enter__(self) -> "VmcSender":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class VmcOut:
    """One performer's VMC stream to one or more receivers: the daemon's ``vmc://`` sink.

    A ``tap`` callable, when given, sees every frame's datagrams before they are sent
    (tests capture the exact bytes for the determinism check)."""

    def __init__(self, targets: list[tuple[str, int]], bundled: bool = True, tap=None):
        self.sender = VmcSender(targets, bundled=bundled)
        self.tap = tap

    def send(self, root_position: np.ndarray, rotations: np.ndarray, offsets: np.ndarray, time: float) -> None:
        VmcOut.send_many([(self, root_position, rotations, offsets)], time)

    @staticmethod
    def send_many(rows: list, time: float) -> None:
        """Frames of many performers at one ``time``, (sink, root position, rotations,
        offsets) each: the daemon's tick. The values of all frames of one root mode are
        worked out and checked in one pass (per frame, numpy's per-call cost was most of
        the encode); then each sink writes and sends its own."""
        by_mode: dict[str, list] = {}
        for row in rows:
            by_mode.setdefault(row[0].sender.encoder.root_mode, []).append(row)
        for root_mode, group in by_mode.items():
            values = frame_values(np.array([r[1] for r in group], dtype=np.float64),
                                  np.array([r[2] for r in group], dtype=np.float64),
                                  np.array([r[3] for r in group], dtype=np.float64), time, root_mode)
            words = values.astype(_BIG_F32).view(np.uint32)
            for (sink, *_), fine, frame_words in zip(group, sendable(values).tolist(), words):
                s = sink.sender
                if not fine:
                    s.frames_rejected += 1  # non-finite pose: never put NaN on the wire
                    continue
                datagrams = s.encoder.write(frame_words)
                s.frames_sent += 1
                if sink.tap is not None:
                    sink.tap(datagrams)
                s.send_datagrams(datagrams)

    def counters(self) -> dict:
        return self.sender.counters()

    def close(self) -> None:
        self.sender.close()


def open_sink(url, targets: list[tuple[str, int]], bundled: bool = True, tap=None) -> VmcOut:
    """The sink factory registered for ``vmc://`` (see ``sinks.py``); ``?bundled=0|1``
    overrides the daemon's --unbundled for this receiver."""
    opts = url.take({"bundled": (bool, None)})
    return VmcOut(targets, bundled if opts["bundled"] is None else opts["bundled"], tap)


# ------------------------------------------------ trackers as VMC (stylecast emulate --to vmc://)

class VmcTrackerSink:
    """Tracker samples as VMC tracker messages (``vmc://HOST:PORT``), one bundle per frame.

    Lost trackers are simply not sent (VMC has no status flag for them)."""

    def __init__(self, url: str):
        self.sender = VmcSender.from_urls([url])
        self.frames = 0

    def send(self, samples: list) -> None:  # trackers.TrackerSample (vmc/ never imports trackers/ at run time)
        msgs = [_VmcTracker(s) for s in samples if s.valid]
        if not samples:
            return
        try:
            datagrams = encode_trackers(msgs, time=samples[0].timestamp)
        except ValueError:  # non-finite pose: never put NaN on the wire
            return
        self.sender.send_datagrams(datagrams)
        self.frames += 1

    @property
    def stats(self) -> dict:
        return self.sender.counters()

    def close(self) -> None:
        self.sender.close()


class _VmcTracker:
    """The shape ``vmc_out.encode_trackers`` reads (kind, serial, position, rotation, local)."""

    __slots__ = ("kind", "serial", "position", "rotation", "local")

    def __init__(self, s: TrackerSample):
        self.kind = s.role.vmc_kind.lower()
        self.serial = s.role.serial
        self.position = s.position
        self.rotation = s.orientation
        self.local = False
