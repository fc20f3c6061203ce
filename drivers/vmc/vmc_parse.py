"""VMC parsing: VMC/OSC datagrams into humanoid pose frames and tracker samples.

``VmcParser`` is pure: feed it bytes and the sender's address, get completed frames (no
socket, injectable time). ``vmc_in.VmcReceiver`` owns the socket that feeds it.

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
``too_many_performers``; ``vmc_in.VmcReceiver`` adds ``recv_error`` and ``queue_overflow``.
Volume counters sit in the same dict: ``datagrams``, ``messages``, ``frames``,
``expired_frames``. Extra trailing arguments are ignored, as the protocol asks.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from stylecast.motion import rotations as rot
from stylecast.motion.clip import PoseFrame
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default
from stylecast.motion.unity import position_from_unity, position_to_unity, rotation_from_unity

from stylecast.drivers.vmc.osc_packets import decode

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
