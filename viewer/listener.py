"""VMC in: the drivers' parser and receiver feed the performer table, one thread per port.

The viewer is a marionette like any other: it uses ``drivers.vmc.vmc_parse`` (the same parser the
daemon uses for live input, so both agree on Unity space, framing and what is ignored)
and never the daemon itself. Each listening port has a role (the main ports carry the
restyled stream, ``--input-port`` the daemon's copy of the unrestyled input) and, when
the viewer listens on a range of ports, a slot: the daemon sends performer k to PORT + k.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

from stylecast.drivers.vmc.vmc_in import VmcReceiver
from stylecast.drivers.vmc.vmc_parse import VmcFrame, VmcParser
from stylecast.motion.humanoid import humanoid_skeleton_default

from .performers import PerformerTable

VOLUME_COUNTERS = {"datagrams", "messages", "frames", "expired_frames"}  # traffic, not problems
# Stream offsets are used only when they describe a plausible body: a sender that sends
# zero (or absurd) local positions would otherwise crush or explode the skeleton.
MIN_BODY_CM, MAX_BONE_CM = 50.0, 300.0
MAX_REMEMBERED = 256


def performer_label(name: str) -> str:
    return name.removeprefix("vmc:")


class Intake:
    """Completed VMC frames -> the performer table (no sockets: tests feed bytes)."""

    def __init__(self, table: PerformerTable, role: str, clock: Callable[[], float] = time.monotonic,
                 use_stream_offsets: bool = True, slot: int | None = None) -> None:
        self.table, self.role, self.clock, self.slot = table, role, clock, slot
        self.use_stream_offsets = use_stream_offsets
        self.parser = VmcParser(clock=clock)
        self._default = humanoid_skeleton_default()
        self._skeletons: dict[str, tuple[np.ndarray, object]] = {}

    def feed(self, datagram: bytes, sender: tuple, now: float | None = None) -> int:
        """Parse one datagram; returns how many frames it completed. Never raises on bad bytes."""
        return self.accept(self.parser.feed(datagram, sender, self.clock() if now is None else now))

    def expire(self, now: float | None = None) -> int:
        return self.accept(self.parser.expire(self.clock() if now is None else now))

    def accept(self, frames: list[VmcFrame]) -> int:
        for f in frames:
            if f.pose is None:  # trackers only: nothing to draw
                continue
            label = performer_label(f.performer)
            if self.use_stream_offsets:
                self._maybe_set_skeleton(label, f.offsets, f.timestamp)
            self.table.update_pose(self.role, label, f.pose.root_position, f.pose.rotations,
                                   f.sender_time, f.timestamp, self.slot)
        return len(frames)

    def _maybe_set_skeleton(self, label: str, offsets: np.ndarray, now: float) -> None:
        if len(self._skeletons) > MAX_REMEMBERED:  # senders that come and go on new ports
            self._skeletons.clear()
        known = self._skeletons.get(label)
        if known is not None and np.allclose(known[0], offsets, atol=0.05):
            return  # offsets repeat every frame: rebuild only when they change
        lengths = np.linalg.norm(offsets, axis=1)
        plausible = np.all(np.isfinite(lengths)) and lengths.sum() > MIN_BODY_CM and lengths.max() < MAX_BONE_CM
        skeleton = self._default.with_offsets(offsets) if plausible else self._default
        self._skeletons[label] = (np.array(offsets, copy=True), skeleton)
        self.table.set_skeleton(self.role, label, skeleton, now, self.slot)

    def ignored(self) -> dict[str, int]:
        """Reasons and counts of what the parser dropped (call from the parser's thread)."""
        return {k: v for k, v in self.parser.counters.items() if k not in VOLUME_COUNTERS and v}


class Listener:
    """One UDP port (``drivers.vmc.vmc_in.VmcReceiver``) and the thread that drains it into an Intake."""

    def __init__(self, intake: Intake, bind: str, port: int) -> None:
        self.intake = intake
        self.receiver = VmcReceiver(bind, port, parser=intake.parser, clock=intake.clock)
        self._ignored: dict[str, int] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"viewer-{intake.role}", daemon=True)

    @property
    def address(self) -> tuple[str, int]:
        return self.receiver.address

    def start(self) -> "Listener":
        self._thread.start()
        return self

    def _run(self) -> None:
        failures = 0
        while not self._stop.is_set():
            try:
                self.intake.accept(self.receiver.poll(timeout=0.05))
            except Exception:  # a bug must not silently end the viewer's input: count, go on
                failures += 1
                self._stop.wait(0.05)
            ignored = self.intake.ignored()  # read here, in the only thread that writes them
            if failures:
                ignored["listener_error"] = failures
            with self._lock:
                self._ignored = ignored

    def ignored(self) -> dict[str, int]:
        with self._lock:
            return dict(self._ignored)

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
        self.receiver.close()
