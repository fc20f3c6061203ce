"""Resampling a clip to another frame rate: slerp for rotations, linear for positions.

Frame i of the result sits at time i / fps. The result spans the same duration as the
input, so 30 -> 60 -> 30 fps returns the original frames (slerp at a key is the key).
"""

from __future__ import annotations

import numpy as np

from . import rotations as rot
from .clip import Clip
from .errors import UserError

# The highest frame rate a file is resampled to: mocap systems record at up to a few
# hundred frames per second; past this a typo (1e9) asked numpy for 68 GB.
MAX_FILE_FPS = 1000.0


def check_frame_rate(fps: float, option: str = "--fps") -> float:
    """``fps`` as given to ``option``, or one sentence saying what is wrong with it."""
    if not (0 < fps <= MAX_FILE_FPS):  # NaN fails it too
        raise UserError(f"{option} must be a frame rate above 0 and at most {MAX_FILE_FPS:g} frames per second, "
                        f"got {fps:g}")
    return float(fps)


def resample(clip: Clip, fps: float) -> Clip:
    if not fps > 0:
        raise ValueError(f"frame rate must be positive, got {fps}")
    if abs(fps - clip.fps) < 1e-9 or clip.num_frames < 2:
        return clip.replace(fps=float(fps))
    span = (clip.num_frames - 1) / clip.fps
    count = int(np.floor(span * fps + 1e-6)) + 1
    src_time = np.arange(count) * (clip.fps / fps)  # in source frames
    lo = np.minimum(np.floor(src_time + 1e-9).astype(int), clip.num_frames - 1)
    hi = np.minimum(lo + 1, clip.num_frames - 1)
    frac = np.clip(src_time - lo, 0.0, 1.0)
    J = len(clip.skeleton)
    rotations = rot.slerp(clip.rotations[lo], clip.rotations[hi], np.repeat(frac[:, None], J, axis=1))
    lerp = lambda a: a[lo] + (a[hi] - a[lo]) * frac.reshape(-1, *([1] * (a.ndim - 1)))  # noqa: E731
    translations = None if clip.translations is None else lerp(clip.translations)
    return Clip(clip.skeleton, rot.canonical_hemisphere(rotations), lerp(clip.root_positions), float(fps), translations)


class StreamResampler:
    """Live resampling of one performer's stream onto the output rate (pure: no I/O, no clock).

    ``feed(frame)`` takes a source's ``PoseFrame`` stamped in the source's own time base,
    at whatever rate the source runs (30, 72, 90, 120 Hz, or irregular), and returns the
    frames of a grid of step 1/fps anchored at the first frame's time, each interpolated
    between the two source frames around it (slerp for rotations, linear for the root):
    the streaming twin of ``resample``. A grid frame is emitted once a source frame at or
    after its time has arrived, so this adds at most one source frame period of latency.
    A source frame that falls on the grid (a 60 Hz source) is passed through unchanged.

    A gap longer than ``max_gap`` (the sender paused) or time going backwards (the
    sender restarted) re-anchors the grid at the new frame instead of interpolating
    across it (``restarts`` counts them); a frame with an old or equal time is dropped
    (``stale`` counts them).
    """

    ON_GRID = 1e-6  # seconds: a source time this close to a grid time is that grid frame

    def __init__(self, fps: float, max_gap: float = 0.25):
        if not fps > 0:
            raise ValueError(f"frame rate must be positive, got {fps}")
        self.step = 1.0 / fps
        self.max_gap = float(max_gap)
        self._prev = None
        self._t0 = 0.0
        self._k = 0
        self.restarts = 0
        self.stale = 0

    def _anchor(self, frame):
        if self._prev is not None:
            self.restarts += 1
        self._prev, self._t0, self._k = frame, float(frame.timestamp), 1
        return [frame]

    def feed(self, frame) -> list:
        from .clip import PoseFrame

        prev = self._prev
        t = float(frame.timestamp)
        if prev is None or t - prev.timestamp > self.max_gap or t < prev.timestamp - self.max_gap:
            return self._anchor(frame)
        if t <= prev.timestamp:
            self.stale += 1
            return []
        out = []
        t_prev, span = float(prev.timestamp), t - float(prev.timestamp)
        while True:
            g = self._t0 + self._k * self.step  # from the anchor, so the grid never drifts
            if g > t + self.ON_GRID:
                break
            if abs(g - t) <= self.ON_GRID:
                out.append(PoseFrame(frame.performer, g, frame.root_position, frame.rotations))
            else:
                a = (g - t_prev) / span
                out.append(PoseFrame(frame.performer, g,
                                     prev.root_position + a * (frame.root_position - prev.root_position),
                                     rot.slerp(prev.rotations, frame.rotations, a)))
            self._k += 1
        self._prev = frame
        return out
