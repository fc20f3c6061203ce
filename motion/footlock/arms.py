"""Arm swing (``ArmSwing``): styles swing their arms by their own amounts while they walk
and run, and the generator barely changes it.

Real elderly walks swing the hands half as far as normal ones (the hands' forward swing
against the hips, ``models.metrics.arm_swing``: 7.1 against 13.8 cm), youthful walks 1.5x,
active and youthful runs 1.8-1.9x (``models.arm_swing.ARM_SWINGS``, the training clips). The
multistyle model towards elderly kept the input's swing (13.1 cm), and its held-out walks
read elderly in 11-35 % of windows on the judges; with the swing scaled to the elderly
takes' in a diagnostic, 72-91 %. So, like the pace, the stream takes the style's swing:
each arm bone's (upper and lower arm) motion about its own slow mean in the INPUT,
d_t = log(q_t * m_t^-1) with m_t a low-pass of the input's rotations over ``arm_mean_tau``
frames, is scaled by the style's ratio: the output's bone becomes exp((g - 1) d_t) times
the restyled one, which leaves the restyle's own change of the arm as it was and adds
(g - 1) of the performer's swing. The gain g goes with the input's low-passed speed over
ground (``ContactSettings.arm_swing``: 1 standing, the walks' ratio at the source style's
walking pace, the runs' at its running pace, straight lines between), so a wave or a raise
(standing: their arms ARE the action) is left alone, and with the share of the restyle
shown (none in pass-through or a late word's fade); the gain is low-passed, so a new style
or a fade never steps the arms.

Causal, state carried from block to block: a clip at once and a stream a frame at a time
give the same frames (``swing_frames`` is the daemon's tick, all performers in one pass).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter, lfilter_zi

from .. import rotations as rot
from ..humanoid import HUMANOID_BONES
from ..smoothing import TriplePole, lfilter_one_step, triple_pole
from .pace import TELEPORT_STEP
from .settings import ContactSettings

# The bones whose swing is scaled: the hands' swing is the upper and lower arms' (the
# shoulders and hands barely swing in the Bandai walks).
SWING_BONES = ("LeftUpperArm", "LeftLowerArm", "RightUpperArm", "RightLowerArm")
SWING_INDEX = [HUMANOID_BONES.index(name) for name in SWING_BONES]


class ArmSwing:
    """The output's arm swing at the style's amount (see the module docstring)."""

    def __init__(self, settings: ContactSettings):
        self.set_points(settings.arm_swing)
        self._b, self._a = triple_pole(settings.arm_mean_tau)
        self._settled = lfilter_zi(self._b, self._a)[:, None]  # the state per unit of a held input
        self._mean_state: np.ndarray | None = None  # (3, 16): the low-pass of the input arms' quaternions
        self._last: np.ndarray | None = None  # (4, 4): the input arms' last quaternions, sign-aligned
        self._speed = TriplePole(settings.pace_tau)
        self._extra = TriplePole(settings.pace_tau)  # g - 1, low-passed
        self._previous: tuple | None = None  # the last input root's (x, z)
        self._last_step = 0.0  # the input's last horizontal step that was not a teleport
        self._first_step = True  # the stream's first step is yet to come
        self._moving = False  # any gain but 1 so far (a stream that never had one skips the work)

    def set_points(self, points) -> None:
        """A new swing (a new model, direction or style; () = the input's own), as
        (input speed cm/frame, gain) points; the gain moves to it over the low-pass."""
        points = sorted((float(a), float(b)) for a, b in points)
        self.on = bool(points)
        self._xs = [0.0] + [a for a, _ in points]
        self._ys = [1.0] + [b for _, b in points]

    def gain(self, speed: float) -> float:
        """The swing's gain at the input's speed ``speed`` (cm/frame): 1 at rest, straight
        lines through the points, the last point's gain beyond it; 1 without points."""
        if not self.on:
            return 1.0
        return float(np.interp(speed, self._xs, self._ys))

    def apply(self, roots: np.ndarray, inputs: np.ndarray, outputs: np.ndarray,
              mix: np.ndarray | None = None) -> np.ndarray | None:
        """The next frames in order: input roots (n, 3), input and restyled rotations (n, J, 4)
        and the share of the restyle shown (n,) (None: all of it) -> the outputs with the
        arms' swing scaled (a new array), or None where nothing changes."""
        n = len(roots)
        shown = [1.0] * n if mix is None else np.broadcast_to(mix, (n,)).tolist()
        extra = [self._extra_of_frame(x, z, s) for (x, _, z), s in zip(np.asarray(roots).tolist(), shown)]
        arms = self._aligned(np.asarray(inputs, np.float64)[:, SWING_INDEX])
        if self._mean_state is None:
            self._mean_state = self._settled * arms[0].reshape(-1)
        mean, self._mean_state = lfilter(self._b, self._a, arms.reshape(n, -1), axis=0, zi=self._mean_state)
        if not self._moving:
            return None
        out = np.array(outputs, np.float64)
        out[:, SWING_INDEX] = _swung(arms, mean.reshape(n, 4, 4), np.asarray(extra), out[:, SWING_INDEX])
        return out

    def _extra_of_frame(self, x: float, z: float, shown: float) -> float:
        """One frame of the gain's recurrence on Python floats: g - 1, low-passed. The
        speed is followed whether or not a swing is set, so a style set live starts from
        the performer's speed."""
        first_step = self._first_step and self._previous is not None
        px, pz = (x, z) if self._previous is None else self._previous
        self._previous = (x, z)
        step = math.hypot(x - px, z - pz)
        if step > TELEPORT_STEP:  # a looped clip or a tracker glitch (``Pace``): not a speed
            step = self._last_step
        self._last_step = step
        if first_step:  # as ``Pace``: the low-passes start settled on the stream's first step
            self._first_step = False
            self._speed.settle_on(step)
            self._extra.settle_on(shown * (self.gain(step) - 1.0))
        speed = self._speed.step(step)
        if not (self.on or self._moving):
            return 0.0
        extra = self._extra.step(shown * (self.gain(speed) - 1.0))
        self._moving = self._moving or extra != 0.0
        return extra

    def _aligned(self, arms: np.ndarray) -> np.ndarray:
        """(n, 4, 4) quaternions, each bone's signs made continuous with the last frame's
        (q and -q are one rotation; the low-pass needs one of them)."""
        arms = arms.copy()
        before = arms[0] if self._last is None else self._last
        for t in range(len(arms)):  # n is a block's frames (one in the daemon)
            flip = np.sum(arms[t] * before, axis=-1) < 0.0
            arms[t, flip] *= -1.0
            before = arms[t]
        self._last = arms[-1].copy()
        return arms


def _swung(arms: np.ndarray, mean: np.ndarray, extra: np.ndarray, restyled: np.ndarray) -> np.ndarray:
    """exp(extra * log(arm * mean^-1)) * restyled, per frame and bone: (n, 4, 4) input arms,
    their low-passed (unnormalised) mean, (n,) extra = g - 1 and the restyled arms."""
    mean = mean / np.linalg.norm(mean, axis=-1, keepdims=True)
    swing = rot.log_map(rot.multiply(arms, rot.inverse(mean)))
    return rot.multiply(rot.exp_map(extra[:, None, None] * swing), restyled)


def swing_frames(swings: list[ArmSwing], roots: np.ndarray, inputs: np.ndarray, outputs: np.ndarray,
                 shown: list[float]) -> list[int]:
    """One frame of each of many streams (the daemon's tick): input roots (P, 3), input and
    restyled rotations (P, J, 4) (``outputs`` changed in place) and the share shown of
    each; the same as each ``apply``, in one vectorised pass for the low-pass. Returns the
    rows it changed."""
    extra = [s._extra_of_frame(x, z, f) for s, (x, _, z), f in zip(swings, roots.tolist(), shown)]
    arms = np.stack([s._aligned(inputs[k, SWING_INDEX][None])[0] for k, s in enumerate(swings)])
    for s, arm in zip(swings, arms):
        if s._mean_state is None:
            s._mean_state = s._settled * arm.reshape(-1)
    state = np.stack([s._mean_state for s in swings], axis=1)  # (3, P, 16)
    mean, state = lfilter_one_step(swings[0]._b, swings[0]._a, arms.reshape(len(swings), -1), state)
    for k, s in enumerate(swings):
        s._mean_state = state[:, k]
    rows = [k for k, s in enumerate(swings) if s._moving]
    if rows:
        outputs[np.ix_(rows, SWING_INDEX)] = _swung(arms[rows], mean.reshape(-1, 4, 4)[rows],
                                                    np.asarray(extra)[rows], outputs[np.ix_(rows, SWING_INDEX)])
    return rows
