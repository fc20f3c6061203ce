"""Resampling a clip to another frame rate: slerp for rotations, linear for positions.

Frame i of the result sits at time i / fps. The result spans the same duration as the
input, so 30 -> 60 -> 30 fps returns the original frames (slerp at a key is the key).
"""

from __future__ import annotations

from collections import deque

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

    A sender at the output rate or a whole fraction of it (60, 30, 20, 15 Hz) whose stamps
    are rounded or jitter is *locked* (``locked``): over its last ``LOCK_INTERVALS`` frame
    intervals, each counted as the whole number of grid steps nearest it (at least one),
    the time per step is within ``LOCK_BAND`` of the grid's, or their whole error within
    ``SNAP``. Its frame within ``SNAP`` of a grid time is that grid frame, as sent: its
    poses are taken at its own rate, and the noise is in the stamps. The grid follows its
    frames by ``FOLLOW`` of each one's offset (a first-order loop), so a sender a little
    off the rate (59.94 Hz, a clock 100 ppm fast) stays on it, 0.13 ms behind at 59.94 Hz.
    Real senders stamp /VMC/Ext/T with their uptime as a float32 (Unity's ``Time.time``),
    rounded to 0.12 ms after 20 minutes. Taken exactly, half of their frames landed a hair
    before their grid time and each waited a whole period for the next frame: at hop 4 /
    delay 5 a 60 Hz sender's p99 was 108 ms against 90 with exact stamps, a 30 Hz one's
    123 against 90 (``bench/bench_stamps.py``); and interpolating between noisy stamps
    shook the motion (1.5 ms of jitter: 1.73x the root's jerk). Other rates (50, 72, 90,
    120, 144 Hz, irregular) are interpolated at the grid's own times, as before: snapping
    their frames would shift them by up to ``SNAP`` at uneven moments, which shows as jerk.
    ``snapped``: the last grid frame ``feed`` returned is the source frame itself.

    A gap longer than ``max_gap`` (the sender paused) or time going backwards (the
    sender restarted) re-anchors the grid at the new frame instead of interpolating
    across it (``restarts`` counts them); a frame with an old or equal time is dropped
    (``stale`` counts them).
    """

    ON_GRID = 1e-6  # seconds: a source time this close to a grid time is that grid frame
    SNAP = 0.25  # of a grid step (4.2 ms at 60 fps): a locked sender's frame this close is on the grid
    FOLLOW = 0.125  # of a snapped frame's offset the grid moves towards it
    # Stamps jittering by 1.5 ms move a 60 Hz sender's time per step over 32 intervals by
    # 0.6 % at most; 57 Hz is 5 % off and must not lock: snapped whenever its frames drift
    # near the grid, it would jerk.
    LOCK_BAND = 0.01
    LOCK_INTERVALS = 32

    def __init__(self, fps: float, max_gap: float = 0.25):
        if not fps > 0:
            raise ValueError(f"frame rate must be positive, got {fps}")
        self.step = 1.0 / fps
        self.max_gap = float(max_gap)
        self._prev = None
        self._t0 = 0.0
        self._k = 0
        self._intervals: deque = deque()  # (seconds, grid steps) of the last LOCK_INTERVALS
        self._span = self._steps = 0.0  # their sums, kept as they come and go
        self.restarts = 0
        self.stale = 0
        self.snapped = False

    def _anchor(self, frame):
        if self._prev is not None:
            self.restarts += 1
        self._prev, self._t0, self._k = frame, float(frame.timestamp), 1
        self._intervals.clear()
        self._span = self._steps = 0.0
        self.snapped = True
        return [frame]

    def _count(self, interval: float) -> None:
        # Each interval counted as whole grid steps, so a dropped frame (two steps) keeps
        # the time per step; running sums, as this runs per frame and performer.
        steps = max(1, round(interval / self.step))
        self._intervals.append((interval, steps))
        self._span += interval
        self._steps += steps
        if len(self._intervals) > self.LOCK_INTERVALS:
            old, old_steps = self._intervals.popleft()
            self._span -= old
            self._steps -= old_steps

    @property
    def locked(self) -> bool:
        """The sender runs at the output rate or a whole fraction of it (``LOCK_BAND``)."""
        # Or their whole error within SNAP: the session judges a half-rate start on the
        # stream's second frame, with one interval to go on, and 1 % of it (0.3 ms) is less
        # than a sender's scheduling keeps to. A rate this lets in for an interval or two
        # (50, 72 Hz) drops out on the next.
        expected = self._steps * self.step
        return bool(self._intervals) and abs(self._span - expected) <= max(self.LOCK_BAND * expected,
                                                                             self.SNAP * self.step)

    def feed(self, frame) -> list:
        from .clip import PoseFrame

        prev = self._prev
        t = float(frame.timestamp)
        if prev is None or t - prev.timestamp > self.max_gap or t < prev.timestamp - self.max_gap:
            return self._anchor(frame)
        if t <= prev.timestamp:
            self.stale += 1
            self.snapped = False
            return []
        out = []
        t_prev, span = float(prev.timestamp), t - float(prev.timestamp)
        self._count(span)
        locked = self.locked
        on_grid = self.SNAP * self.step if locked else self.ON_GRID
        self.snapped = False
        while True:
            g = self._t0 + self._k * self.step  # from the anchor, so the grid never drifts...
            if g > t + on_grid:
                break
            if abs(g - t) <= on_grid:
                if locked and abs(g - t) > self.ON_GRID:
                    self._t0 += self.FOLLOW * (t - g)  # ...but follows a locked sender's frames
                out.append(PoseFrame(frame.performer, g, frame.root_position, frame.rotations))
                self.snapped = True
            else:
                a = (g - t_prev) / span
                out.append(PoseFrame(frame.performer, g,
                                     prev.root_position + a * (frame.root_position - prev.root_position),
                                     rot.slerp(prev.rotations, frame.rotations, a)))
            self._k += 1
        self._prev = frame
        return out
