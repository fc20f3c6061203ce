"""Gait amplitude (``GaitAmplitude``): styles swing their arms and lift their hips by their own
amounts while they walk and run, and neither the generator nor the hips' height stage gives
it.

Real elderly walks swing the hands half as far as normal ones (``models.metrics.arm_swing``:
7.1 against 13.8 cm) and lift and drop the hips half as much (``metrics.hips_bob``: 0.7
against 1.3 cm); youthful walks swing 1.5x, active and masculine walks bob 1.9-2.2x
(``models.gait_amplitude``, the training clips). The multistyle model towards elderly kept
the input's swing, and the hips, following the restyled legs' bend (``PelvisHeight``), bobbed
more; its held-out walks read elderly in 11-35 % of windows, and as turning walks. So, like
the pace, the stream takes the style's amplitudes:

- arms: each upper arm's motion about its own slow mean in the INPUT,
  d_t = log(q_t * m_t^-1), m_t a low-pass of the input's rotations over ``amplitude_tau``
  frames, is scaled by the style's ratio g: the output's bone becomes exp((g - 1) d_t) times
  the restyled one, which leaves the restyle's own change of the arm as it was and adds
  (g - 1) of the performer's swing (g at most ``MAX_SWING_GAIN``); each elbow, a hinge,
  bends by (g - 1) times its input flexion's way from its own low-pass more
  (``hinges.add_elbow_flexion``);
- hips: the output root's height about a low-pass of itself (the hips' height stage's, the
  pace's and the input's rise and fall together) is scaled by the hips' ratio, at most 1
  (``MAX_BOB_GAIN``), before the leg IK puts the planted feet back on the floor from there.

Each gain goes with the input's low-passed speed over ground (``ContactSettings.arm_swing``,
``hips_bob``: 1 standing, the walks' ratio at the source style's walking pace, the runs' at its
running pace, straight lines between), so a wave or a raise (standing: the arms ARE the
action) is left alone, and with the share of the restyle shown (none in pass-through or a
late word's fade); the gains are low-passed, so a new style or a fade never steps the body.

Causal, state carried from block to block: a clip at once and a stream a frame at a time
give the same frames (``amplitude_frames`` is the daemon's tick, all performers in one pass).
"""

from __future__ import annotations

import bisect
import math

import numpy as np
from scipy.signal import lfilter, lfilter_zi

from .. import rotations as rot
from ..hinges import add_elbow_flexion, elbow_flexion
from ..humanoid import HUMANOID_BONES
from ..smoothing import TriplePole, lfilter_one_step, triple_pole
from .pace import TELEPORT_STEP
from .settings import ContactSettings

# The bones whose swing is scaled as free rotations: the shoulder joints (ball joints). The
# elbows are hinges (``motion.hinges``): only their flexion's swing is scaled. Scaling the
# lower arms as free rotations bent them off their hinge (the multistyle model towards
# youthful: 9.1 degrees beyond the input's, p99; towards active 2.4); the upper arms alone
# left a held-out walk given the elderly swing at 0.69 of its hands' swing, not 0.51.
SWING_BONES = ("LeftUpperArm", "RightUpperArm")
ARMS = len(SWING_BONES)
CHANNELS = ARMS * 4 + 2  # the low-passed signal: the upper arms' quaternions, the elbows' flexion
# The most the arms' swing is scaled: a swing amplified g times is g times the hands' jerk
# there. With active's runs at 1.88x (youthful's 1.80x) the multistyle model's jerk towards
# active rose 1.075 -> 1.102, over the 1.10 bar; at most 1.5x, 1.094 (youthful 1.093 ->
# 1.082), for 1.1 points of active's style on the worst judge of each panel (youthful's:
# 0.0 and 0.2; the model card, "Arm swing and hip bob").
MAX_SWING_GAIN = 1.5
# The most the hips' bob is scaled: a bob only lessens (as a pace only slows). Hips lifted and
# dropped by more than the restyled legs asked for stretched and folded the planted legs in
# the IK: the multistyle model's largest one-frame jerk towards active 2.2 -> 4.4x the
# input's, masculine 1.9 -> 3.3x, their jerk ratio 1.07 -> 1.28 and 1.01 -> 1.14 (over the
# 1.10 bar), and their walks read as walks in 11 and 23 % of windows (49 and 64 % before);
# towards exhausted (walks 1.35x) 89 -> 69 %. Lessened, towards elderly, its walks read as
# walks in 57 % (15 % before) and elderly in 100 % (the model card, "Arm swing and hip bob").
MAX_BOB_GAIN = 1.0
SWING_INDEX = [HUMANOID_BONES.index(name) for name in SWING_BONES]


class _Gain:
    """One amplitude's gain: (speed, gain) points from (0, 1), its g - 1 low-passed."""

    def __init__(self, points, tau: float, most: float = math.inf):
        self.most = most  # the largest gain given
        self.set_points(points)
        self.extra = TriplePole(tau)

    def set_points(self, points) -> None:
        points = sorted((float(a), float(b)) for a, b in points)
        self.on = bool(points)
        self._xs = [0.0] + [a for a, _ in points]
        self._ys = [1.0] + [b for _, b in points]

    def at(self, speed: float) -> float:
        """The gain at ``speed``: ``np.interp`` written out on Python floats (per frame and
        performer in the daemon's tick, where np.interp's call was most of the recurrence)."""
        if not self.on:
            return 1.0
        xs, ys = self._xs, self._ys
        if speed >= xs[-1]:
            gain = ys[-1]
        else:
            k = max(bisect.bisect_right(xs, speed), 1)
            gain = ys[k - 1] + (ys[k] - ys[k - 1]) * (speed - xs[k - 1]) / (xs[k] - xs[k - 1])
        return min(gain, self.most)


class GaitAmplitude:
    """The output's arm swing and hip bob at the style's amounts (see the module docstring)."""

    def __init__(self, settings: ContactSettings):
        self._arms = _Gain(settings.arm_swing, settings.pace_tau, most=MAX_SWING_GAIN)
        self._hips = _Gain(settings.hips_bob, settings.pace_tau, most=MAX_BOB_GAIN)
        self._b, self._a = triple_pole(settings.amplitude_tau)
        self._settled = lfilter_zi(self._b, self._a)[:, None]  # the state per unit of a held input
        self._arm_state: np.ndarray | None = None  # (3, CHANNELS): the low-pass of the input arms
        self._last: np.ndarray | None = None  # (ARMS, 4): the input arms' last quaternions, sign-aligned
        self._height = TriplePole(settings.amplitude_tau)  # of the output root's height
        self._height_started = False
        self._speed = TriplePole(settings.pace_tau)
        self._previous: tuple | None = None  # the last input root's (x, z)
        self._last_step = 0.0  # the input's last horizontal step that was not a teleport
        self._first_step = True  # the stream's first step is yet to come
        self._moving = [False, False]  # arms, hips: any gain but 1 so far (else the work is skipped)

    def set_points(self, arm_swing=(), hips_bob=()) -> None:
        """New amplitudes (a new model, direction or style; () = the input's own), as
        (input speed cm/frame, gain) points; the gains move to them over the low-pass."""
        self._arms.set_points(arm_swing)
        self._hips.set_points(hips_bob)

    def gains(self, speed: float) -> tuple[float, float]:
        """The arms' and the hips' gains at the input's speed ``speed`` (cm/frame): 1 at rest,
        straight lines through the points, the last point's gain beyond it; 1 without
        points; the arms' at most MAX_SWING_GAIN, the hips' at most MAX_BOB_GAIN."""
        return self._arms.at(speed), self._hips.at(speed)

    @property
    def active(self) -> tuple[bool, bool]:
        """Whether the arms' and the hips' parts have work: a gain set, or one still easing
        back to 1. Their low-passes run only then (a session that never had a gain costs
        nothing but its speed), and start settled on the frame they start at."""
        return self._arms.on or self._moving[0], self._hips.on or self._moving[1]

    def apply(self, roots: np.ndarray, inputs: np.ndarray, outputs: np.ndarray, heights: np.ndarray,
              mix: np.ndarray | None = None) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The next frames in order: input roots (n, 3), input and restyled rotations (n, J, 4),
        the output root's heights (n,) and the share of the restyle shown (n,) (None: all of
        it) -> the outputs with the arms' swing scaled (a new array) and the new heights, each
        None where nothing changes."""
        n = len(roots)
        arms_on, hips_on = self.active
        shown = [1.0] * n if mix is None else np.broadcast_to(mix, (n,)).tolist()
        extra = np.array([self._extras_of_frame(x, z, s) for (x, _, z), s in zip(np.asarray(roots).tolist(), shown)])
        swung = bobbed = None
        if arms_on:
            inputs = np.asarray(inputs, np.float64)
            arms = _arm_signal(inputs, self._aligned_to(inputs[0]))
            self._last = arms[-1, :ARMS * 4].reshape(ARMS, 4)
            if self._arm_state is None:
                self._arm_state = self._settled * arms[0]
            mean, self._arm_state = lfilter(self._b, self._a, arms, axis=0, zi=self._arm_state)
            if self._moving[0]:
                swung = _swung(arms, mean, extra[:, 0], outputs)
        if hips_on:
            heights = np.asarray(heights, np.float64)
            if not self._height_started:
                self._height_started = True
                self._height.settle_on(float(heights[0]))
            level = self._height.run(heights)
            if self._moving[1]:
                bobbed = level + (1.0 + extra[:, 1]) * (heights - level)
        return swung, bobbed

    def _aligned_to(self, first: np.ndarray) -> np.ndarray:
        """The upper arms' quaternions (ARMS, 4) the next frame's signs follow: the last
        frame's, or the first frame's own."""
        return first[SWING_INDEX] if self._last is None else self._last

    def _extras_of_frame(self, x: float, z: float, shown: float) -> tuple[float, float]:
        """One frame of the gains' recurrence on Python floats: each g - 1, low-passed. The
        speed is followed whether or not a gain is set, so a style set live starts from the
        performer's speed."""
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
            for gain in (self._arms, self._hips):
                gain.extra.settle_on(shown * (gain.at(step) - 1.0))
        speed = self._speed.step(step)
        extras = []
        for k, gain in enumerate((self._arms, self._hips)):
            if not (gain.on or self._moving[k]):
                extras.append(0.0)
                continue
            extra = gain.extra.step(shown * (gain.at(speed) - 1.0))
            self._moving[k] = self._moving[k] or extra != 0.0
            extras.append(extra)
        return extras[0], extras[1]



def _arm_signal(inputs: np.ndarray, before: np.ndarray) -> np.ndarray:
    """Input rotations (n, J, 4) of one stream, in order, or one frame each of many (n
    streams: ``before`` (n, ARMS, 4) then) -> what the arms' low-pass runs on (n, CHANNELS):
    the upper arms' quaternions, each bone's signs made continuous with the frame before's
    (``before``: the stream's last; q and -q are one rotation, the low-pass needs one of
    them), and the elbows' flexion."""
    arms = inputs[:, SWING_INDEX].copy()
    if before.ndim == 3:  # many streams, one frame each
        arms[np.sum(arms * before, axis=-1) < 0.0] *= -1.0
    else:
        for t in range(len(arms)):  # a block's frames in order
            arms[t, np.sum(arms[t] * before, axis=-1) < 0.0] *= -1.0
            before = arms[t]
    return np.concatenate([arms.reshape(len(arms), -1), elbow_flexion(inputs)], axis=1)


def _swung(arms: np.ndarray, mean: np.ndarray, extra: np.ndarray, outputs: np.ndarray) -> np.ndarray:
    """The outputs (n, J, 4) with (g - 1) = ``extra`` (n,) of the input arms' swing added:
    ``arms`` (n, CHANNELS), the input arms' signal (``_arm_signal``), and ``mean`` its
    low-pass. Each upper arm becomes exp(extra * log(arm * mean^-1)) * its restyled rotation,
    each elbow bends by extra times its flexion's way from its mean more (a hinge still)."""
    n = len(arms)
    upper, level = arms[:, :ARMS * 4].reshape(n, ARMS, 4), mean[:, :ARMS * 4].reshape(n, ARMS, 4)
    level = level / np.linalg.norm(level, axis=-1, keepdims=True)
    swing = rot.log_map(rot.multiply(upper, rot.inverse(level)))
    out = np.array(outputs, np.float64)
    out[:, SWING_INDEX] = rot.multiply(rot.exp_map(extra[:, None, None] * swing), out[:, SWING_INDEX])
    return add_elbow_flexion(out, extra[:, None] * (arms[:, ARMS * 4:] - mean[:, ARMS * 4:]))


def amplitude_frames(amplitudes: list[GaitAmplitude], roots: np.ndarray, inputs: np.ndarray, outputs: np.ndarray,
                     heights: np.ndarray, shown: list[float]) -> None:
    """One frame of each of many streams (the daemon's tick): input roots (P, 3), input and
    restyled rotations (P, J, 4) and output root heights (P,) (``outputs`` and ``heights``
    changed in place) and the share shown of each; the same as each ``apply``, the arms of
    all in one vectorised pass (per stream, numpy's per-call cost would be most of it)."""
    active = [g.active for g in amplitudes]
    extra = np.array([g._extras_of_frame(x, z, f) for g, (x, _, z), f in zip(amplitudes, roots.tolist(), shown)])
    for k, (g, (_, hips_on)) in enumerate(zip(amplitudes, active)):
        if hips_on:  # a scalar each: Python floats
            height = float(heights[k])
            if not g._height_started:
                g._height_started = True
                g._height.settle_on(height)
            level = g._height.step(height)
            if g._moving[1]:
                heights[k] = level + (1.0 + extra[k, 1]) * (height - level)
    at = [k for k, (arms_on, _) in enumerate(active) if arms_on]
    if not at:
        return
    swings = [amplitudes[k] for k in at]
    frames = inputs[at]
    arms = _arm_signal(frames, np.stack([g._aligned_to(q) for g, q in zip(swings, frames)]))  # (A, CHANNELS)
    for g, arm in zip(swings, arms):
        g._last = arm[:ARMS * 4].reshape(ARMS, 4)
        if g._arm_state is None:
            g._arm_state = g._settled * arm
    state = np.stack([g._arm_state for g in swings], axis=1)  # (3, A, CHANNELS); the streams share one tau
    mean, state = lfilter_one_step(swings[0]._b, swings[0]._a, arms, state)
    for k, g in enumerate(swings):
        g._arm_state = state[:, k]
    rows = [i for i, g in enumerate(swings) if g._moving[0]]
    if rows:
        at_rows = [at[i] for i in rows]
        outputs[at_rows] = _swung(arms[rows], mean[rows], extra[at_rows, 0], outputs[at_rows])
