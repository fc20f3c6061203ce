"""Pace (``Pace``, ``--pace style``, the default): styles cover ground at their own speed,
and the judges see it (an exhausted run is slower). The root's horizontal steps are
scaled to the target style's pace; each foot carries its own share of the lag, growing with
its own steps (so a planted foot stays put) and taken back while it swings, so strides
shorten and no planted foot slides.
"""

from __future__ import annotations

import bisect
import math

import numpy as np

from ..smoothing import TriplePole
from .settings import ContactSettings

# The fastest pace against the performer's (``Pace``): a body ahead of its performer needs
# strides longer than the performer's from the same planted feet, and the planted leg
# stretched out behind the hips to full reach and popped its knee as the lock let go (the
# multistyle model made active, whose walks are 1.30x as fast: 7.3x the input's largest
# one-frame jerk, against 3.0x at the input's pace). So a style's pace only slows.
MAX_PACE_RATIO = 1.0
# cm a frame beyond which the input's root did not walk but jumped (30 m/s, three times a
# sprint): a looped clip starting over, a tracker losing its origin; the pace's lag is reset
TELEPORT_STEP = 50.0


class Pace:
    """The output's horizontal travel at the style's pace (``ContactSettings.pace``), causal,
    state carried from block to block like ``PelvisHeight``.

    Real styles cover ground at their own speed (exhausted runs at 0.80x the normal ones'
    in the training clips, walks at 0.94x), and the judges see it: real held-out exhausted
    runs given the normal pace read exhausted in 28 % of windows. So each horizontal step
    of the root is shortened by the pace's ratio at the input's low-passed speed (never
    lengthened: ``MAX_PACE_RATIO``), in proportion to how much of the restyle is shown (the
    seam blender's mix: none in pass-through, bypass or a late word's fade). The body falls
    behind its performer by ``shift``, which walking back takes back (a constant ratio maps
    the performer's path onto a smaller copy of it). The slowdown is low-passed too, so a
    new style, a new intensity or a fade never steps the body's speed.

    A foot cannot simply go with the body: a planted foot would slide back. Each foot has
    its own shift, which grows by the slowdown's share of the input foot's OWN step (a
    planted foot barely moves, so it stays where it landed; a swinging one covers the
    slowed stride with the input's one-humped speed), and while it is free it also takes
    back what it lags the body's shift, ``carry_rate`` of it per centimetre it steps (a
    turn or a change of pace leaves some), in proportion to how free its lock is. Before
    2026-11-30 a free foot went with the BODY's step and took the stance's lag back at 15 %
    a frame: as a foot lifted, the body's step pulled it back faster than it swung forward,
    and its speed slumped mid-swing (the multistyle model towards elderly: every held-out
    swing dipped, 210 -> 40 -> 270 cm/s; ``metrics.swing_dips``). The foot lock puts a
    planted foot on the input's ankle less its shift, and a free foot where the restyled
    leg puts it, moved by how far its shift lags the body's (``_carry_free_feet``), or on
    the input's own path less its shift (``ContactSettings.swing_path``): shorter strides
    at the same cadence."""

    def __init__(self, settings: ContactSettings):
        self.set_points(settings.pace)
        self.rate = float(settings.carry_rate)
        self._speed = TriplePole(settings.pace_tau)
        self._slowdown = TriplePole(settings.pace_tau)
        self._previous: tuple | None = None  # the last input root's (x, z)
        self._previous_ankles: list | None = None  # ...and the input's ankles' [[x, z], [x, z]]
        self._shift = [0.0, 0.0]  # the body's, x and z (cm)
        self._feet = [[0.0, 0.0], [0.0, 0.0]]  # each foot's
        self._moving = False  # any shift so far (a stream that never slowed skips the work)
        self._last_step = 0.0  # the input's last horizontal step that was not a teleport
        self._first_step = True  # the stream's first step is yet to come (``_step``)

    def set_points(self, points) -> None:
        """A new pace (a new model, direction or style; () = the input's own); the body's
        speed moves to it over the low-pass."""
        points = sorted((float(a), float(b)) for a, b in points)
        self.on = bool(points)
        self._xs = [0.0] + [a for a, _ in points]
        self._ys = [0.0] + [b for _, b in points]

    def ratio(self, speed: float) -> float:
        """Output speed over input speed at ``speed`` (cm/frame): straight lines through the
        points from (0, 0), the last point's ratio beyond it; 1 without points. At most
        MAX_PACE_RATIO."""
        xs, ys = self._xs, self._ys
        if not self.on:
            return 1.0
        if speed >= xs[-1]:
            ratio = ys[-1] / xs[-1]
        elif speed <= 1e-9:
            ratio = ys[1] / xs[1]
        else:
            k = bisect.bisect_right(xs, speed)
            ratio = (ys[k - 1] + (ys[k] - ys[k - 1]) * (speed - xs[k - 1]) / (xs[k] - xs[k - 1])) / speed
        return min(ratio, MAX_PACE_RATIO)

    def track(self, roots: np.ndarray, ankles: np.ndarray, weights: np.ndarray, mix: np.ndarray | None = None):
        """The next frames in order: input roots (n, 3), the input's ankles (n, 2, 3), the lock
        weights (n, 2) and the share of the restyle shown (n,) (None: all of it) -> the
        body's shift (n, 2: x, z) and each foot's (n, 2, 2), to take off the input's travel;
        None while there is none. A recurrence on Python floats (``track_one_frame`` is the
        daemon's frame)."""
        feet_xz = np.asarray(ankles)[:, :, [0, 2]]
        if not (self.on or self._moving):
            self._previous = tuple(np.asarray(roots)[-1, [0, 2]].tolist())
            self._previous_ankles = feet_xz[-1].tolist()
            return None
        self._moving = True
        n = len(roots)
        mix = [1.0] * n if mix is None else np.broadcast_to(mix, (n,)).tolist()
        body, feet = np.empty((n, 2)), np.empty((n, 2, 2))
        for i, ((x, _, z), ankle_xz, (left, right), shown) in enumerate(
                zip(roots.tolist(), feet_xz.tolist(), weights.tolist(), mix)):
            body[i], feet[i] = self._step(x, z, ankle_xz, left, right, shown)
        return body, feet

    def track_one_frame(self, x: float, z: float, ankles_xz: list, left: float, right: float, shown: float):
        """``track`` of one frame on Python floats (the daemon's case): the input root's x and
        z, the input's ankles' [[x, z], [x, z]], the two lock weights and the share shown ->
        the body's shift [x, z] and each foot's [[x, z], [x, z]] (new lists), or None while
        there is none."""
        if not (self.on or self._moving):
            self._previous, self._previous_ankles = (x, z), ankles_xz
            return None
        self._moving = True
        return self._step(x, z, ankles_xz, left, right, shown)

    def _step(self, x: float, z: float, ankles_xz: list, left: float, right: float,
              shown: float) -> tuple[list, list]:
        """One frame of the recurrence (see ``track``); the new shifts, as new lists."""
        (sx, sz), rate = self._shift, self.rate
        first_step = self._first_step and self._previous is not None
        px, pz = (x, z) if self._previous is None else self._previous
        before = ankles_xz if self._previous_ankles is None else self._previous_ankles
        self._previous, self._previous_ankles = (x, z), ankles_xz
        dx, dz = x - px, z - pz
        step = math.hypot(dx, dz)
        feet = self._feet
        foot_steps = [(ax - bx, az - bz) for (ax, az), (bx, bz) in zip(ankles_xz, before)]
        if step > TELEPORT_STEP:
            # A looped clip or a tracker glitch: the avatar goes with its performer and
            # the lag starts again from nothing (the step would otherwise be scaled and
            # leave the feet a stride's worth of metres behind the body).
            sx = sz = 0.0
            feet = [[0.0, 0.0], [0.0, 0.0]]
            dx = dz = 0.0
            foot_steps = [(0.0, 0.0), (0.0, 0.0)]
            step = self._last_step
        self._last_step = step
        if first_step:
            # The stream's first step (its second frame): the low-passes start settled on it,
            # as on a pace held before the stream, since no travel was shown before it to
            # ease from. From rest, a run started live went at the input's speed for its
            # first half second or so: held-out runs started live read exhausted in 66.7 % of
            # windows, 87.5 % with this (83.3 % for a stream that had been running; a scratch
            # panel of three judges).
            self._first_step = False
            self._speed.settle_on(step)
            self._slowdown.settle_on(shown * (1.0 - self.ratio(step)))
        speed = self._speed.step(step)
        slow = self._slowdown.step(shown * (1.0 - self.ratio(speed)))
        self._feet = [[fx + slow * fdx + catch * (sx - fx), fz + slow * fdz + catch * (sz - fz)]
                      for (fx, fz), (fdx, fdz), catch in
                      ((foot, foot_step, (1.0 - w) * min(rate * math.hypot(*foot_step), 1.0))
                       for foot, foot_step, w in zip(feet, foot_steps, (left, right)))]
        self._shift = [sx + slow * dx, sz + slow * dz]
        return self._shift, self._feet
