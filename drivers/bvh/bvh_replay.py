"""``bvh:///path/clip.bvh?loop=1&speed=1.0``: a recorded clip replayed as a live source.

The clip is read once and retargeted to the canonical humanoid; frames are then handed
out at the clip's OWN rate (30 fps for the Bandai files), paced by the daemon's clock:
frame i is due at ``t0 + i / (fps * speed)`` and carries that time as its timestamp,
like any live source. The daemon's session resamples it to the output rate, as it does
every source (``motion.resample.StreamResampler``): the replay does not resample.
``speed`` only changes the timeline (speed 2 plays the clip in half the time).
"""

from __future__ import annotations

import math

import numpy as np

from stylecast.motion.bvh import require_frames
from stylecast.motion.clip import Clip, PoseFrame
from stylecast.motion.errors import UserError

from stylecast.drivers.sources import Source
from stylecast.drivers.urls import EndpointUrl

MAX_BURST_SECONDS = 2.0  # a poll after a long stall returns at most 2 s (the newest frames)


def humanoid_motion(clip: Clip, user_map: dict | None = None) -> Clip:
    """Any-rig clip -> humanoid clip (T-pose-relative rotations), at the clip's own rate."""
    from stylecast.motion.humanoid import HUMANOID_BONES, Retarget

    if tuple(clip.skeleton.names) == HUMANOID_BONES:
        return clip
    return Retarget.for_clip(clip, user_map).to_humanoid(clip)


class ReplaySource(Source):
    """Replays a humanoid motion at its own rate, paced by the clock handed to ``start``/``poll``."""

    def __init__(self, motion: Clip, performer: str, loop: bool = False, speed: float = 1.0):
        if not 0.05 <= speed <= 20.0:
            raise UserError(f"replay speed {speed} is out of range; use a value between 0.05 and 20")
        require_frames(motion, f"the clip for performer {performer!r}")
        self.performer = performer
        self.skeleton = motion.skeleton
        self.rotations = np.ascontiguousarray(motion.rotations, dtype=np.float64)
        self.root_positions = np.ascontiguousarray(motion.root_positions, dtype=np.float64)
        self.period = 1.0 / (motion.fps * speed)  # seconds between frames on the replayed timeline
        self.loop = loop
        self._t0: float | None = None
        self._next = 0  # index of the next frame to hand out (counts on across loops)
        self.skipped = 0

    @property
    def num_frames(self) -> int:
        return len(self.rotations)

    def start(self, now: float) -> None:
        self._t0 = float(now)
        self._next = 0

    def _available(self, now: float) -> int:
        """How many frames have become due by ``now`` (frame i at t0 + i * period)."""
        if self._t0 is None:
            self.start(now)
        n = math.floor((now - self._t0) / self.period + 1e-6) + 1
        return n if self.loop else min(n, self.num_frames)

    def poll(self, now: float) -> list[PoseFrame]:
        stop = self._available(now)
        burst = max(1, int(MAX_BURST_SECONDS / self.period))
        if stop - self._next > burst:
            self.skipped += stop - burst - self._next
            self._next = stop - burst
        frames = []
        T = self.num_frames
        for i in range(self._next, stop):
            k = i % T
            frames.append(PoseFrame(self.performer, self._t0 + i * self.period,
                                    self.root_positions[k], self.rotations[k]))
        self._next = max(self._next, stop)
        return frames

    @property
    def finished(self) -> bool:
        return not self.loop and self._next >= self.num_frames

    def counters(self) -> dict:
        return {"skipped": self.skipped}


def open_source(url: EndpointUrl, performer: str) -> ReplaySource:
    opts = url.take({"loop": (bool, False), "speed": (float, 1.0), "name": (str, ""), "map": (str, "")})
    if not url.path:
        raise UserError(f"{url.text}: give a file, as in bvh:///path/clip.bvh")
    from stylecast.motion.bvh import read_bvh

    clip = require_frames(read_bvh(url.path), url.path)  # before the retargeting reads its motion
    user_map = None
    if opts["map"]:
        from stylecast.motion.humanoid import load_user_map

        user_map = load_user_map(opts["map"])
    return ReplaySource(humanoid_motion(clip, user_map), opts["name"] or performer,
                        loop=opts["loop"], speed=opts["speed"])
