"""VMC input: the UDP sockets that feed the VMC parser, and the daemon's ``vmc://`` source.

Two layers, as in python-osc (dispatcher apart from server): ``vmc_parse.VmcParser`` is
pure (feed it bytes and the sender's address, get completed frames; no socket, injectable
time), and ``VmcReceiver`` owns a UDP socket and feeds a parser, either when polled or
from the process's one receive thread (``drivers.receive_hub``: a selector over every
input socket, bounded work per wake-up, so junk at one port cannot starve the output
clock).

What is read, how frames are completed and what is counted: ``vmc_parse``.

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
from typing import TYPE_CHECKING

import numpy as np

from stylecast.motion.clip import PoseFrame
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import humanoid_skeleton_default

from stylecast.drivers.vmc.osc_packets import check_port
from stylecast.drivers.vmc.sender_time import SenderTime
from stylecast.drivers.vmc.vmc_parse import TrackerSample, VmcFrame, VmcParser
from stylecast.drivers.urls import parse_vmc_url

if TYPE_CHECKING:
    from stylecast.drivers.urls import EndpointUrl


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
