"""What the viewer knows about each performer it hears, shared by listener and renderer.

The listener threads write, the render loop reads a copy once per frame; one lock guards
the table and is held only for array copies, so neither side waits on the other.

Latency from /VMC/Ext/T: the value is "sender-relative seconds", so ``recv - T`` is the
sender's clock offset plus the transport delay. stylecast's daemon stamps T with its
monotonic clock, which on the same host *is* the viewer's clock (CLOCK_MONOTONIC is
system-wide), so a small non-negative ``recv - T`` is read as the latency itself. Any
other offset means another clock: then only the part above the smallest offset seen is
meaningful, and it is shown as jitter. T is a float32 on the wire, so the figure moves in
steps of the float32 spacing at the host's uptime (0.1 ms after 20 minutes, 2 ms after 5
hours, 8 ms after a day): a coarse reading on a long-running host, the daemon's own status
(restyle p50/p99) is the exact one.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from stylecast.motion.humanoid import HUMANOID_BONES
from stylecast.motion.skeleton import Skeleton

ROLES = ("restyled", "input")
RATE_WINDOW_S = 1.0  # received frame rate = frames in the last second
OFFSET_WINDOW = 600  # frames of (recv - T) kept for the offset estimate (10 s at 60 Hz)
RECENT_FRAMES = 30  # the latency shown is the median of the last half second
SHARED_CLOCK_MAX_S = 2.0  # recv - T within [0, 2 s): the sender uses our monotonic clock


@dataclass
class Performer:
    key: tuple
    role: str
    label: str
    slot: int
    skeleton: Skeleton
    root: np.ndarray = field(default_factory=lambda: np.array([0.0, 95.0, 0.0]))
    rotations: np.ndarray = field(default_factory=lambda: np.tile([0.0, 0.0, 0.0, 1.0], (len(HUMANOID_BONES), 1)))
    frames: int = 0
    ignored_values: int = 0  # non-finite or zero-length values replaced by the previous pose
    last_seen: float = 0.0
    arrivals: deque = field(default_factory=lambda: deque(maxlen=512))
    offsets: deque = field(default_factory=lambda: deque(maxlen=OFFSET_WINDOW))

    def rate(self, now: float) -> float:
        recent = [t for t in self.arrivals if now - t <= RATE_WINDOW_S]
        if len(recent) < 2:
            return 0.0
        span = recent[-1] - recent[0]
        return (len(recent) - 1) / span if span > 0 else 0.0

    def latency(self) -> tuple[str, float] | None:
        """("latency", s) when the sender shares our clock, else ("jitter", s); recent median."""
        if not self.offsets:
            return None
        recent = sorted(list(self.offsets)[-RECENT_FRAMES:])
        median = recent[len(recent) // 2]
        if 0.0 <= min(recent) and median < SHARED_CLOCK_MAX_S:
            return "latency", median
        return "jitter", median - min(self.offsets)


def sanitise(previous: np.ndarray, rotations: np.ndarray) -> tuple[np.ndarray, int]:
    """Unit quaternions; a bone whose value is non-finite or zero keeps its previous value
    (a NaN from a sender's prediction filter must not make the skeleton vanish)."""
    q = np.asarray(rotations, np.float64)
    if q.shape != previous.shape:
        return previous, int(previous.shape[0])
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    bad = ~np.isfinite(norm[:, 0]) | (norm[:, 0] < 1e-6)
    with np.errstate(invalid="ignore", divide="ignore"):
        q = np.where(bad[:, None], previous, q / np.where(bad[:, None], 1.0, norm))
    return q, int(bad.sum())


class PerformerTable:
    """Performers keyed by (role, sender or tag); each role numbers its performers in order
    of first appearance, and the n-th input pairs with the n-th restyled performer."""

    def __init__(self, skeleton: Skeleton, forget_after: float = 10.0) -> None:
        self._skeleton = skeleton
        self._lock = threading.Lock()
        self._performers: dict[tuple, Performer] = {}
        self.forget_after = forget_after

    def _get(self, role: str, ident: str, now: float, slot: int | None = None) -> Performer:
        key = (role, ident)
        perf = self._performers.get(key)
        if perf is None:
            # The port's slot when it has one (the daemon sends performer k to PORT + k,
            # restyled and input alike, so equal slots pair up); otherwise the lowest free
            # number, so a performer that comes back after being forgotten takes its old place.
            used = {p.slot for p in self._performers.values() if p.role == role}
            if slot is None or slot in used:
                slot = min(set(range(len(used) + 1)) - used)
            perf = self._performers[key] = Performer(key, role, ident, slot, self._skeleton)
        perf.last_seen = now
        return perf

    def update_pose(self, role: str, ident: str, root: np.ndarray, rotations: np.ndarray,
                    stream_time: float | None, now: float, slot: int | None = None) -> None:
        with self._lock:
            perf = self._get(role, ident, now, slot)
            perf.rotations, bad = sanitise(perf.rotations, rotations)
            root = np.asarray(root, np.float64)
            if root.shape == (3,) and np.all(np.isfinite(root)):
                perf.root = root
            else:
                bad += 1
            perf.ignored_values += bad
            perf.frames += 1
            perf.arrivals.append(now)
            if stream_time is not None and math.isfinite(stream_time):
                perf.offsets.append(now - stream_time)

    def set_skeleton(self, role: str, ident: str, skeleton: Skeleton, now: float, slot: int | None = None) -> None:
        """Bone offsets a stream carries (its /VMC/Ext/Bone/Pos positions) replace the default."""
        with self._lock:
            self._get(role, ident, now, slot).skeleton = skeleton

    def snapshot(self, now: float) -> list[Performer]:
        """Copies for one render frame, sorted by (slot, role); forgets silent performers."""
        with self._lock:
            for key in [k for k, p in self._performers.items() if now - p.last_seen > self.forget_after]:
                del self._performers[key]
            out = [Performer(p.key, p.role, p.label, p.slot, p.skeleton, p.root.copy(), p.rotations.copy(),
                             p.frames, p.ignored_values, p.last_seen, deque(p.arrivals), deque(p.offsets))
                   for p in self._performers.values()]
        return sorted(out, key=lambda p: (p.slot, ROLES.index(p.role) if p.role in ROLES else 9))

    def __len__(self) -> int:
        with self._lock:
            return len(self._performers)
