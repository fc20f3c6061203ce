"""``bvh:///path/clip.bvh?loop=1&speed=1.0``: a recorded clip replayed as a live source.

The clip is read once, retargeted to the canonical humanoid and resampled so that one
stream frame is 1/60 s of the *replayed* timeline: speed s resamples the content to
60/s fps and then plays it at 60 fps (speed 2 = half as many frames, same output rate).
Everything is precomputed, so ``poll`` is an index computation: frame i is due at
``t0 + i / 60`` on the daemon's clock, which makes a fake-clock replay exact.
"""

from __future__ import annotations

import math

import numpy as np

from stylecast.motion.clip import Clip, PoseFrame
from stylecast.motion.errors import UserError

from .sources import Source
from .urls import EndpointUrl

STREAM_FPS = 60.0
MAX_BURST_FRAMES = 120  # a poll after a long stall returns at most 2 s (the newest frames)


def humanoid_motion(clip: Clip, user_map: dict | None = None) -> Clip:
    """Any-rig clip -> humanoid clip (T-pose-relative rotations), at the clip's own rate."""
    from stylecast.motion.humanoid import HUMANOID_BONES, Retarget

    if tuple(clip.skeleton.names) == HUMANOID_BONES:
        return clip
    return Retarget.for_clip(clip, user_map).to_humanoid(clip)


class ReplaySource(Source):
    """Replays a humanoid motion at 60 fps, paced by the clock handed to ``start``/``poll``."""

    def __init__(self, motion: Clip, performer: str, loop: bool = False, speed: float = 1.0):
        from stylecast.motion.resample import resample

        if not 0.05 <= speed <= 20.0:
            raise UserError(f"replay speed {speed} is out of range; use a value between 0.05 and 20")
        stream = resample(motion, STREAM_FPS / speed)
        if stream.num_frames < 1:
            raise UserError(f"clip for performer {performer!r} has no frames")
        self.performer = performer
        self.skeleton = motion.skeleton
        self.rotations = np.ascontiguousarray(stream.rotations, dtype=np.float64)
        self.root_positions = np.ascontiguousarray(stream.root_positions, dtype=np.float64)
        self.loop = loop
        self._t0: float | None = None
        self._next = 0  # stream index of the next frame to hand out
        self.skipped = 0

    @property
    def num_frames(self) -> int:
        return len(self.rotations)

    def start(self, now: float) -> None:
        self._t0 = float(now)
        self._next = 0

    def _available(self, now: float) -> int:
        """How many stream frames have become due by ``now`` (frame i at t0 + i/60)."""
        if self._t0 is None:
            self.start(now)
        n = math.floor((now - self._t0) * STREAM_FPS + 1e-6) + 1
        return n if self.loop else min(n, self.num_frames)

    def poll(self, now: float) -> list[PoseFrame]:
        stop = self._available(now)
        if stop - self._next > MAX_BURST_FRAMES:
            self.skipped += stop - MAX_BURST_FRAMES - self._next
            self._next = stop - MAX_BURST_FRAMES
        frames = []
        T = self.num_frames
        for i in range(self._next, stop):
            k = i % T
            frames.append(PoseFrame(self.performer, self._t0 + i / STREAM_FPS,
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

    clip = read_bvh(url.path)
    user_map = None
    if opts["map"]:
        from stylecast.motion.humanoid import load_user_map

        user_map = load_user_map(opts["map"])
    return ReplaySource(humanoid_motion(clip, user_map), opts["name"] or performer,
                        loop=opts["loop"], speed=opts["speed"])
