"""VMC input: parse VMC/OSC datagrams into humanoid pose frames and tracker samples.

Two layers, as in python-osc (dispatcher apart from server): ``VmcParser`` is pure (feed
it bytes and the sender's address, get completed frames; no socket, injectable time),
and ``VmcReceiver`` owns a UDP socket and feeds a parser, either when polled or from the
process's one receive thread (``drivers.receive_hub``: a selector over every input
socket, bounded work per wake-up, so junk at one port cannot starve the output clock).

What is read (Unity space converted by ``motion.unity``, the only place that flips axes):

* /VMC/Ext/Root/Pos and /VMC/Ext/Bone/Pos for the 22 HUMANOID_BONES. The root is the
  parent of the Hips (VMC spec), so the Hips' world pose is root * Hips-local; that
  becomes ``PoseFrame.root_position`` (cm) and ``rotations[0]``. Other bones' local
  positions are kept as ``VmcFrame.offsets`` (the sender's proportions); finger, eye and
  jaw bones are ignored (counted as ``ignored_bone``).
* /VMC/Ext/{Hmd,Con,Tra}/Pos and their /Local variants as ``TrackerSample``s.
* /VMC/Ext/T (sender time, and the end-of-frame marker) and /VMC/Ext/OK (loaded flag).

Frame completion (per performer):

1. /VMC/Ext/T completes the pending frame. Senders that send T, VirtualMotionCapture and
   stylecast among them, send it once per frame after the bones, so this is exact even
   when a frame spans several bundles (VirtualMotionCapture splits every 12 bones; we
   split at 1472 bytes). Once a sender has sent T, T alone frames it, so a sender that
   repeats Root in every bundle of a frame is not split by rule 2.
2. For senders never seen to send T: /VMC/Ext/Root/Pos arriving while the pending frame
   already holds root or bone data completes that frame and starts the next. Every VMC
   performer sends Root first, so unbundled streams without T are framed by it (one
   frame of latency).
3. For senders never seen to send T: the end of a bundle completes the frame once the
   root and all 22 bones have arrived since the frame began (a sender that puts a whole
   frame in one bundle is framed without waiting for the next Root).
4. ``expire(now)`` completes a frame pending longer than ``max_frame_age`` (a stream
   that never sends Root or T still flows), and forgets performers idle for
   ``idle_timeout``. ``VmcReceiver.poll`` calls it.

A frame's timestamp is the receive time (the parser's clock) of its first datagram; the
sender's own T value is kept as ``sender_time``. Bones missing from a frame keep their
previous value, identity (and default humanoid offsets) if never seen;
``VmcFrame.bones_updated`` says how many the frame itself carried.

Performers: by default each sender address (host, port) is one performer, named
"vmc:HOST:PORT". For one port per performer, give each receiver a ``performer_id``:
everything arriving on that port is then that performer, even when the sender restarts
from a new source port.

Robustness: nothing raises on bad input; everything dropped or ignored is counted in
``VmcParser.counters`` by reason: the OSC decoder's reasons (``osc_packets``) plus
``wrong_type``, ``missing_args``, ``non_finite``, ``bad_quaternion`` (the message is
dropped, the performer keeps its previous value), ``unknown_address``, ``ignored_vmc``
(VMC messages we do not use, e.g. blend shapes), ``ignored_bone`` and
``too_many_performers``; ``VmcReceiver`` adds ``recv_error`` and ``queue_overflow``.
Volume counters sit in the same dict: ``datagrams``, ``messages``, ``frames``,
``expired_frames``. Extra trailing arguments are ignored, as the protocol asks.

``open_source`` is the daemon's ``vmc://`` source factory (``drivers.sources``).
"""

from __future__ import annotations

import math
import select
import socket
import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from stylecast.motion import rotations as rot
from stylecast.motion.clip import PoseFrame
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default
from stylecast.motion.unity import (position_from_unity, position_to_unity, rotation_from_unity)

from stylecast.drivers.vmc.osc_packets import check_port, decode
from stylecast.drivers.vmc.sender_time import SenderTime
from stylecast.drivers.urls import parse_vmc_url

if TYPE_CHECKING:
    from stylecast.drivers.urls import EndpointUrl

_BONE_INDEX = {name: j for j, name in enumerate(HUMANOID_BONES)}
_POSE_TAGS = "sfffffff"
_TRACKERS = {
    f"/VMC/Ext/{a}/Pos{suffix}": (kind, bool(suffix))
    for a, kind in (("Hmd", "hmd"), ("Con", "con"), ("Tra", "tra")) for suffix in ("", "/Local")
}
_IDENTITY7 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class TrackerSample:
    kind: str  # "hmd", "con" or "tra"
    serial: str
    position: np.ndarray  # (3,) cm, internal space
    rotation: np.ndarray  # (4,) xyzw, internal space
    local: bool = False  # from a /Local address: raw device space, not avatar-scaled


@dataclass(frozen=True, eq=False)
class VmcFrame:
    performer: str
    timestamp: float  # receive clock, first datagram of the frame
    pose: PoseFrame | None  # None for a frame that carried no root or bone message
    trackers: tuple[TrackerSample, ...]
    bones_updated: int  # humanoid bones carried by this frame (the others were held)
    sender_time: float | None  # the sender's /VMC/Ext/T, if it sent one for this frame
    offsets: np.ndarray  # (22, 3) cm: the sender's local bone positions (Hips row zero)


_default_bones: tuple[tuple, ...] | None = None


def _default_bones_unity() -> list[tuple]:
    """Per bone (px, py, pz, qx, qy, qz, qw) in Unity space before anything is received:
    default humanoid offsets, identity rotations (computed once)."""
    global _default_bones
    if _default_bones is None:
        off = position_to_unity(humanoid_skeleton_default().offsets)
        off[0] = 0.0
        _default_bones = tuple((*map(float, o), 0.0, 0.0, 0.0, 1.0) for o in off)
    return list(_default_bones)


class _Performer:
    """What we know of one sender: last values (Unity space, as received) and the
    frame being assembled."""

    def __init__(self, name: str, now: float) -> None:
        self.name = name
        self.root: tuple = _IDENTITY7
        self.bones: list[tuple] = _default_bones_unity()
        self.sends_t = False
        self.loaded: int | None = None
        self.last_seen = now
        self._new_frame()

    def _new_frame(self) -> None:
        self.has_pose = False
        self.root_in_frame = False
        self.bones_in_frame: set[int] = set()
        self.trackers: list[tuple] = []
        self.first_arrival: float | None = None
        self.sender_time: float | None = None

    @property
    def pending(self) -> bool:
        return self.has_pose or bool(self.trackers)

    def complete(self) -> VmcFrame:
        pose = None
        b = np.array(self.bones)
        q = b[:, 3:] / np.linalg.norm(b[:, 3:], axis=1, keepdims=True)
        if self.has_pose:
            root = np.array(self.root)
            hips_p, hips_q = b[0, :3], q[0]
            if root[:6].any():  # compose root * Hips-local only when the root is not identity
                rq = root[3:] / np.linalg.norm(root[3:])
                hips_p = root[:3] + rot.apply(rq, hips_p)
                hips_q = rot.multiply(rq, hips_q)
            rotations = rotation_from_unity(q)
            rotations[0] = rotation_from_unity(hips_q)
            pose = PoseFrame(self.name, self.first_arrival, position_from_unity(hips_p), rotations)
        offsets = position_from_unity(b[:, :3])
        offsets[0] = 0.0
        trackers = ()
        if self.trackers:
            v = np.array([t[3] for t in self.trackers])
            tp = position_from_unity(v[:, :3])
            tq = rotation_from_unity(v[:, 3:] / np.linalg.norm(v[:, 3:], axis=1, keepdims=True))
            trackers = tuple(TrackerSample(kind, serial, tp[i], tq[i], local)
                             for i, (kind, local, serial, _) in enumerate(self.trackers))
        frame = VmcFrame(self.name, self.first_arrival, pose, trackers, len(self.bones_in_frame),
                         self.sender_time, offsets)
        self._new_frame()
        return frame


class VmcParser:
    """Pure VMC parsing: ``feed(datagram, sender) -> completed frames``. Not thread-safe."""

    def __init__(self, performer_id: str | None = None, clock: Callable[[], float] = time.monotonic,
                 max_performers: int = 64, max_frame_age: float = 0.05, idle_timeout: float = 10.0) -> None:
        self.performer_id = performer_id
        self.clock = clock
        self.max_performers = max_performers
        self.max_frame_age = max_frame_age
        self.idle_timeout = idle_timeout
        self.counters: Counter = Counter()
        self._performers: dict[object, _Performer] = {}

    def _error(self, reason: str) -> None:
        self.counters[reason] += 1

    def _performer(self, sender: tuple, now: float) -> _Performer | None:
        key = self.performer_id or (sender[0], sender[1])
        st = self._performers.get(key)
        if st is None:
            if len(self._performers) >= self.max_performers:
                self.counters["too_many_performers"] += 1
                return None
            host = str(sender[0])
            name = self.performer_id or (f"vmc:[{host}]:{sender[1]}" if ":" in host else f"vmc:{host}:{sender[1]}")
            st = self._performers[key] = _Performer(name, now)
        st.last_seen = now
        return st

    def feed(self, datagram: bytes, sender: tuple, now: float | None = None) -> list[VmcFrame]:
        """Parse one datagram from ``sender`` (host, port); returns the frames it completed."""
        now = self.clock() if now is None else now
        self.counters["datagrams"] += 1
        is_bundle, messages = decode(datagram, self._error)
        if not messages:
            return []
        st = self._performer(sender, now)
        if st is None:
            return []
        out: list[VmcFrame] = []
        counters = self.counters
        counters["messages"] += len(messages)
        for address, tags, args in messages:
            if address == "/VMC/Ext/Bone/Pos" or address == "/VMC/Ext/Root/Pos":
                v = _pose_args(tags, args, counters)
                if v is None:
                    continue
                if address == "/VMC/Ext/Root/Pos":  # starts a frame (rule 2 in the docstring)
                    if st.has_pose and not st.sends_t:
                        out.append(st.complete())
                    st.root = v
                    st.root_in_frame = True
                else:
                    j = _BONE_INDEX.get(args[0])
                    if j is None:
                        counters["ignored_bone"] += 1
                        continue
                    st.bones[j] = v
                    st.bones_in_frame.add(j)
                if st.first_arrival is None:
                    st.first_arrival = now
                st.has_pose = True
            elif address == "/VMC/Ext/T":
                if tags[:1] != "f":
                    counters[_tag_problem(tags, "f")] += 1
                    continue
                if not math.isfinite(args[0]):
                    counters["non_finite"] += 1
                    continue
                st.sends_t = True
                st.sender_time = args[0]
                if st.pending:
                    out.append(st.complete())
            elif address in _TRACKERS:
                v = _pose_args(tags, args, counters)
                if v is None:
                    continue
                kind, local = _TRACKERS[address]
                st.trackers.append((kind, local, args[0], v))
                if st.first_arrival is None:
                    st.first_arrival = now
            elif address == "/VMC/Ext/OK":
                if tags[:1] != "i":
                    counters[_tag_problem(tags, "i")] += 1
                    continue
                st.loaded = args[0]
            elif address.startswith("/VMC/"):
                counters["ignored_vmc"] += 1
            else:
                counters["unknown_address"] += 1
        if (is_bundle and not st.sends_t and st.root_in_frame
                and len(st.bones_in_frame) == len(HUMANOID_BONES)):
            out.append(st.complete())
        counters["frames"] += len(out)
        return out

    def expire(self, now: float | None = None) -> list[VmcFrame]:
        """Complete frames pending longer than ``max_frame_age``; forget idle performers."""
        now = self.clock() if now is None else now
        out = []
        for key, st in list(self._performers.items()):
            if st.pending and st.first_arrival is not None and now - st.first_arrival > self.max_frame_age:
                out.append(st.complete())
            elif not st.pending and now - st.last_seen > self.idle_timeout:
                del self._performers[key]
        if out:
            self.counters["frames"] += len(out)
            self.counters["expired_frames"] += len(out)
        return out

    @property
    def performers(self) -> list[str]:
        return [st.name for st in self._performers.values()]


def _tag_problem(tags: str, expected: str = _POSE_TAGS) -> str:
    return "missing_args" if len(tags) < len(expected) and expected.startswith(tags) else "wrong_type"


def _pose_args(tags: str, args: tuple, counters: Counter) -> tuple | None:
    """The (px, py, pz, qx, qy, qz, qw) of a bone or tracker message (s fff ffff), or None
    with the reason counted; extra trailing arguments are ignored, as the protocol asks."""
    if tags[:8] != _POSE_TAGS:
        counters[_tag_problem(tags)] += 1
        return None
    v = args[1:8]
    # A sum is finite exactly when every term is (float32 values cannot overflow a double).
    if not math.isfinite(v[0] + v[1] + v[2] + v[3] + v[4] + v[5] + v[6]):
        counters["non_finite"] += 1
        return None
    if v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6] < 1e-12:
        counters["bad_quaternion"] += 1
        return None
    return v




class VmcReceiver:
    """A UDP socket feeding a ``VmcParser``. Loopback by default: listening on every
    interface (bind="0.0.0.0") is a choice the user makes explicitly.

    ``poll(timeout=0)`` (alias ``recv_available``) reads every datagram waiting and
    returns the completed frames, without blocking unless a timeout is given. ``start()``
    instead hands the socket to the shared receive thread (``receive_hub``), which reads
    continuously; ``poll`` then returns what it queued (at most ``queue_size`` frames,
    oldest dropped first and counted).
    """

    def __init__(self, bind: str = "127.0.0.1", port: int = 39540, *, performer_id: str | None = None,
                 parser: VmcParser | None = None, clock: Callable[[], float] = time.monotonic,
                 queue_size: int = 4096, rcvbuf: int = 1 << 21) -> None:
        check_port(port, "VMC input")
        self.parser = parser or VmcParser(performer_id, clock=clock)
        self.clock = clock
        try:
            family, _, _, _, sockaddr = socket.getaddrinfo(bind, port, type=socket.SOCK_DGRAM)[0]
            self._sock = socket.socket(family, socket.SOCK_DGRAM)
        except (socket.gaierror, UnicodeError):
            raise UserError(f"cannot listen for VMC on {bind!r}: not an address of this machine; use "
                            f"127.0.0.1 (this machine only) or 0.0.0.0 (every interface)") from None
        try:
            self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
            self._sock.bind(sockaddr)
        except OSError as exc:
            self._sock.close()
            raise UserError(f"cannot listen for VMC on {bind}:{port} ({exc.strerror or exc}); stop the "
                            f"program using that port or choose another, as in vmc://{bind}:39541") from None
        self._sock.setblocking(False)
        self._queue: deque[VmcFrame] = deque()
        self._queue_size = queue_size
        self._ready = threading.Condition()
        self._hub = None  # the receive hub serving this socket, once started
        self._read = 0  # datagrams the last _receive read
        self._delivered = 0  # frames handed to poll's callers (or queued for them)

    @classmethod
    def from_url(cls, url: str, **kwargs) -> "VmcReceiver":
        """``vmc://BIND:PORT[?performer=NAME]``."""
        host, port, opts = parse_vmc_url(url, allowed_options=("performer",))
        if "performer" in opts:
            kwargs.setdefault("performer_id", opts["performer"])
        return cls(host, port, **kwargs)

    @property
    def address(self) -> tuple[str, int]:
        return self._sock.getsockname()[:2]

    @property
    def counters(self) -> Counter:
        return self.parser.counters

    @property
    def delivered(self) -> int:
        """Frames ``poll`` has returned or will return next: with the receive thread,
        those it has queued. The parser counts a frame (``counters["frames"]``) a moment
        before the thread queues it, so a caller that must see a frame on its next poll
        (a test stepping a fake clock) waits on this count, not on the parser's."""
        with self._ready:
            return self._delivered

    def _receive(self, limit: int = 100_000) -> list[VmcFrame]:
        frames: list[VmcFrame] = []
        sock, feed = self._sock, self.parser.feed
        read = 0
        for _ in range(limit):  # bounded so a flood cannot starve the caller forever
            try:
                data, sender = sock.recvfrom(65536)
            except BlockingIOError:
                break
            except OSError:  # e.g. Windows reports an ICMP error of ours as a reset here
                self.parser.counters["recv_error"] += 1
                break
            read += 1
            frames += feed(data, sender, self.clock())
        frames += self.parser.expire(self.clock())
        self._read = read
        return frames

    @property
    def _thread(self):
        """The receive thread serving this socket (the shared hub's), or None."""
        return None if self._hub is None else self._hub.thread

    def poll(self, timeout: float = 0.0) -> list[VmcFrame]:
        if self._hub is not None:
            with self._ready:
                if not self._queue and timeout > 0:
                    self._ready.wait(timeout)
                frames = list(self._queue)
                self._queue.clear()
            return frames
        if timeout > 0:
            select.select([self._sock], [], [], timeout)
        frames = self._receive()
        self._delivered += len(frames)
        return frames

    recv_available = poll

    def start(self, hub=None) -> None:
        """Receive continuously on ``hub`` (default: the process's shared receive hub)."""
        if self._hub is None:
            from .receive_hub import shared_hub

            self._hub = hub or shared_hub()
            self._hub.register(self._sock, self._pump)

    def _pump(self, limit: int) -> int:
        """The hub's handler: read at most ``limit`` datagrams and queue their frames.
        Frames are handed over after every bounded read: under a sustained flood the
        socket never empties, and frames queued only once it had been drained reached the
        daemon seconds late or not at all (hardening, issue 7)."""
        frames = self._receive(limit)
        if frames:
            with self._ready:
                self._queue.extend(frames)
                self._delivered += len(frames)
                overflow = len(self._queue) - self._queue_size
                for _ in range(max(0, overflow)):
                    self._queue.popleft()
                if overflow > 0:
                    self.parser.counters["queue_overflow"] += overflow
                self._ready.notify_all()
        return self._read

    def stop(self) -> None:
        if self._hub is not None:
            self._hub.unregister(self._sock)
            self._hub = None

    def close(self) -> None:
        self.stop()
        self._sock.close()

    def __enter__(self) -> "VmcReceiver":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


INPUT_MODES = ("auto", "bones", "trackers")
MAX_TRACKERS_KEPT = 64  # latest sample per tracker, for status and tests
BONES_PRECEDENCE_S = 0.5  # auto: trackers are solved only after this long without bones
SKELETON_TOLERANCE_CM = 0.05  # offsets that move less than this are not a new skeleton


class _TrackerQueue:
    """The tracker feed a ``SolvedTrackerSource`` pulls from, filled by ``VmcSource``."""

    def __init__(self) -> None:
        self.samples: list = []

    def poll(self) -> list:
        out, self.samples = self.samples, []
        return out


class VmcSource:
    """The daemon's ``vmc://BIND:PORT`` source (``drivers.sources`` interface): one port,
    one performer. Everything arriving on the port is this performer whatever its sender
    address (a restarted sender keeps its identity); run one source per port for several
    performers.

    It accepts what VMC senders send (``input=``):

    * bones (/VMC/Ext/Root/Pos, /Bone/Pos: a performer such as VirtualMotionCapture,
      VSeeFace or SlimeVR): each frame is a pose, and the sender's local bone positions
      become this performer's ``skeleton`` (reported again when they change);
    * trackers (/VMC/Ext/Hmd/Pos, /Con/Pos, /Tra/Pos and their /Local variants: VIVE
      trackers relayed by an assistant, or ``stylecast emulate --to vmc://``): they go
      through the calibrated solver (``solver.SolvedTrackerSource``: T-pose calibration,
      ``calibrate()`` again on /stylecast/calibrate, a lost tracker held and blended back),
      and the calibrated proportions become the ``skeleton``;
    * ``auto`` (default): bones when the sender sends bones, trackers otherwise.

    Trackers find their body role by ``roles=SERIAL:ROLE,...``, else by a serial that
    names a role, else (the headset) by address.
    """

    def __init__(self, bind: str, port: int, performer: str, input: str = "auto", solved=None,
                 role_map: dict | None = None) -> None:
        self.performer = performer
        self.input = input
        self.role_map = role_map or {}
        self.receiver = VmcReceiver(bind, port, performer_id=performer)
        self.trackers: dict[tuple[str, str, bool], TrackerSample] = {}
        self._feed = _TrackerQueue()
        self.solved = solved  # SolvedTrackerSource over self._feed, or None (bones only)
        self._bone_skeleton = None
        self._last_bones = -math.inf
        self.unmapped_trackers = 0
        self.sender_time = SenderTime(performer)

    @property
    def skeleton(self):
        """The performer's proportions as last learnt: from the bones' local positions,
        or from the tracker calibration while trackers drive the pose."""
        if self._using_trackers() and self.solved is not None and self.solved.skeleton is not None:
            return self.solved.skeleton
        return self._bone_skeleton

    def _using_trackers(self, now: float | None = None) -> bool:
        if self.input == "trackers":
            return True
        if self.input == "bones":
            return False
        now = time.monotonic() if now is None else now
        return now - self._last_bones > BONES_PRECEDENCE_S

    def start(self, now: float) -> None:
        self.receiver.start()
        if self.solved is not None:
            self.solved.start(now)

    def poll(self, now: float) -> list[PoseFrame]:
        from stylecast.drivers.trackers.trackers import samples_from_vmc

        bones = []
        for f in self.receiver.poll():
            for t in f.trackers:
                key = (t.kind, t.serial, t.local)
                if key in self.trackers or len(self.trackers) < MAX_TRACKERS_KEPT:  # bounded: serials are free text
                    self.trackers[key] = t
            # Stamped with the sender's own time (/VMC/Ext/T) when it sends a usable one
            # (``SenderTime``): the session resamples by it, so receive jitter does not
            # become motion jitter.
            stamp = self.sender_time.stamp(f.sender_time, f.timestamp)
            if f.pose is not None and self.input != "trackers":
                bones.append(PoseFrame(f.pose.performer, stamp, f.pose.root_position, f.pose.rotations))
                self._learn_skeleton(f.offsets)
            if f.trackers and self.solved is not None:
                samples = samples_from_vmc(f.trackers, stamp, self.role_map)
                self.unmapped_trackers += len({t.serial for t in f.trackers}) - len(samples)
                self._feed.samples += samples
        if bones:
            self._last_bones = time.monotonic()
        solved = self.solved.poll(now) if self.solved is not None else []
        return bones if not self._using_trackers() else solved

    def _learn_skeleton(self, offsets: np.ndarray) -> None:
        known = self._bone_skeleton
        if known is not None and np.abs(known.offsets - offsets).max() < SKELETON_TOLERANCE_CM:
            return
        self._bone_skeleton = humanoid_skeleton_default().with_offsets(offsets)

    def calibrate(self) -> None:
        if self.solved is None:
            raise UserError(f"performer {self.performer!r} takes bones only (input=bones); there are no "
                            f"trackers to calibrate")
        self.solved.calibrate()

    @property
    def finished(self) -> bool:
        return False

    def counters(self) -> dict:
        out = dict(self.receiver.counters)
        if self.solved is not None:
            out.update(self.solved.counters(), unmapped_trackers=self.unmapped_trackers)
        return out

    def close(self) -> None:
        self.receiver.close()


def open_source(url: "EndpointUrl", performer: str) -> VmcSource:
    """Factory for ``drivers.sources``: ``vmc://BIND[:PORT][?name=NAME&input=auto|bones|
    trackers&points=10|6&calibrate=tpose&roles=SERIAL:ROLE,...&blend=S]`` (port 39540,
    the VMC performer port, when omitted; bind 127.0.0.1 when empty)."""
    from stylecast.drivers.trackers.solver import TRACKER_OPTIONS, solved_source
    from stylecast.drivers.trackers.trackers import parse_role_map

    opts = url.take({"name": (str, ""), "input": (str, "auto"), "roles": (str, ""), **TRACKER_OPTIONS})
    if opts["input"] not in INPUT_MODES:
        raise UserError(f"{url.text}: input={opts['input']} must be one of {', '.join(INPUT_MODES)}")
    name = opts["name"] or performer
    role_map = parse_role_map(url.text, opts["roles"])
    port = 39540 if url.port is None else url.port
    source = VmcSource(url.host or "127.0.0.1", port, name, opts["input"], role_map=role_map)
    if opts["input"] != "bones":
        try:
            source.solved = solved_source(url, source._feed, name, opts)
        except BaseException:
            source.close()
            raise
    return source
