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
  (``MAX_BOB_GAIN``), before the leg IK puts the planted feet back on the floor from there;
- the hands' swing across the body (``arm_across``, a style's choice, ``across``): each
  hand's place across the body against its shoulder joint, about its own low-pass, is
  replaced by ``ACROSS_INPUT_SHARE`` of the input's, by the share the style asks for, the
  upper arm turned so the hand goes there (the arms' forward swing and bend stay);
- a raised hand's sway (``wave_sway``, ``raise_sway``, a style's choice): a hand held over
  its elbow has the output's across motion about its low-pass scaled, the same way, by the
  style's gain for a wave where the performer's own hand sways across (a wave), by its gain
  for a raise where it does not; standing only (the gains' points fade them to 1 at the
  source's walking pace);
- the elbows' bend (``elbow_bend``, a style's choice): each elbow's flexion about its own
  low-pass in the OUTPUT keeps its swing, and the low-pass is moved a share of the way to the
  style's mean bend (``hinges.add_elbow_flexion``, a hinge still), none standing. The
  generator bends a run's elbows its own way (towards active 103 degrees, real active runs
  51-91; youthful 50, real 28-37), and the judges took those runs for other styles';
- the hands carried forward (``arm_forward``, a style's choice): each hand's angle forward of
  straight down from its shoulder joint in the OUTPUT (``across.ArmPlaces.forward``) keeps its
  swing about its own low-pass (``FORWARD_TAU``, a slower one), and the low-pass is moved a
  share of the way to the style's mean, the upper arm turned about the level axis across the
  body (``across.forward_turns``), none standing. The generator holds active's walks' hands
  back (5.7 degrees forward, real active walks 19-31), and the judges took those walks for
  turns; it holds feminine's and youthful's runs' further forward than real ones (11 and -9,
  real -8 to -2 and -21 to -13), and the judges took those runs for other styles';
- the elbows carried forward (``elbow_forward``, a style's choice): where each upper arm
  points in its shoulder's frame (``across.elbow_directions``) keeps its swing about its own
  low-pass in the OUTPUT, and the low-pass's angle forward of straight down is moved a share
  of the way to the style's mean, the upper arm turned about the shoulder's level axis
  (``across.elbow_forward_turns``), none standing nor for an arm raised towards level. The
  generator points active's walking upper arms back (held-out walking takes -7 and -16
  degrees, left and right; real active ones 7 and 3 forward), and the walks read less active;
- still arms (``still_arms``, a style's choice, ``still``): where the performer's hand hangs
  still, the output arm's offset from the input's is held at its low-pass (the restyle's
  posture, its motion about it taken away), at any speed over ground; and (``waving_arms``)
  where the performer's raised hand waves, the same hold (the restyle's posture, the
  performer's wave), the elbow given back the share ``waving_elbows`` of the way to the
  performer's own bend;
- the knees' bend (``knee_bend``, a style's choice): each knee's flexion in the OUTPUT is
  scaled so that its own low-pass would go a share of the way to the style's mean bend (the
  stride's swing of the knee scaled with it, a hinge still, ``hinges.scale_knee_flexion``),
  none standing. The generator bent feminine's knees more than the performer (real feminine
  walks and runs bend them less), and the judges took its runs for other styles'. It runs
  before the legs are solved: a planted foot stays where the lock puts it, the leg in the
  air swings straighter;
- the upper body's lean (``performer_lean``, a style's choice, ``lean``): how far the line
  from the spine's joint to the head tilts across the hips' facing, low-passed in the INPUT
  and the OUTPUT, and the spine turned about the hips' level forward axis by a share of the
  difference: the output leans as the performer does on average, its own sway about it kept,
  none standing (a raise of one hand leans away from it, as real raises of every style do).
  The generator leaned its walks to the right (the head 2.0-2.5 cm right of the hips towards
  active and youthful, the performer's and real walks within 0.7 cm of upright), its
  left-turning walks too, where real turns lean into the turn. Last, so the arms' parts read
  the restyle's own torso, and the arms ride on the spine.

Each gain goes with the input's low-passed speed over ground (``ContactSettings.arm_swing``,
``hips_bob``: 1 standing, the walks' ratio at the source style's walking pace, the runs' at its
running pace, straight lines between), so a wave or a raise (standing: the arms ARE the
action) is left alone but for its raised hands' sway, and with the share of the restyle
shown (none in pass-through or a late word's fade); the gains are low-passed, so a new style
or a fade never steps the body.

Causal, state carried from block to block: a clip at once and a stream a frame at a time
give the same frames (``amplitude_frames`` is the daemon's tick, all performers in one pass).
"""

from __future__ import annotations

import bisect
import math
from typing import NamedTuple

import numpy as np
from scipy.signal import lfilter, lfilter_zi

from .. import rotations as rot
from ..hinges import add_elbow_flexion, elbow_flexion, knee_flexion, scale_knee_flexion
from ..humanoid import HUMANOID_BONES
from ..smoothing import TriplePole, lfilter_one_step, smoothstep, triple_pole
from .across import (UPPER_ARM_INDEX, ArmPlaces, arm_places, elbow_directions, elbow_forward_angle,
                     elbow_forward_turns, forward_turns, move_across, sway_turns, turn_upper_arms)
from .lean import leaned, spine_lean
from .pace import TELEPORT_STEP
from .settings import ContactSettings
from .still import hand_steps_squared, held, held_aim, offset_signal, still_gate, waving_gate

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
# What a hand's swing across the body becomes where a style replaces the output's
# (``ContactSettings.arm_across``): this share of the input's, about the shoulder joint. The
# multistyle model towards youthful swung its held-out walks' hands 7.1 cm across against
# the hips (real youthful walks 2.2-3.8, the input 2.3), and the judges took them for turns:
# walks kept as walks 47.5 % on the worst judge of panel 0. All of the output's own across
# swing replaced offline (a diagnostic outside the repository): by the input's (1.0) 3.9 cm,
# 57.5 % (one judge fell from 87.5 to 57.5); by half of it 2.8 cm, 72.5 %; by a quarter
# 2.3 cm, 77.5 %; by none 1.9 cm, 72.5 %; youthful read in 97.8 % of those windows or more
# throughout (the model card, "The arms' swing across"; how much is replaced is the style's:
# ``models.gait_amplitude.ARM_ACROSS_REPLACED``).
ACROSS_INPUT_SHARE = 0.25
# How far a hand sits over its elbow (cm, ``ArmPlaces.raised``) where its sway starts to be
# scaled and where all of the gain applies (a smooth step between): the forearm up, as in
# every real wave and raise (``models.metrics.RAISED_HAND_CM``, 10 cm, reads a wave so); a
# hanging or swinging hand is never scaled.
RAISED_GATE_CM = (5.0, 15.0)
# How far the input's hand sways across about its low-pass (cm, the root of its square's
# low-pass) where a raised hand starts to take the wave's gain rather than the raise's, and
# where it takes all of it (a smooth step between): held-out normal waves sway 7.0-8.8 cm,
# raises 0.6-0.9 (``metrics.raised_hand_sway``). The restyle's own sway cannot tell them
# apart: towards youthful its raises sway 2.0-2.8 cm and its waves of both hands 4.9, and one
# gain on both (1.6) made a third of the raises read as waves.
WAVING_GATE_CM = (2.0, 4.0)


# The elbows' bend part's and the hands' forward part's places in ``GaitAmplitude._gains``
# (each its share, then its pull) and in a frame's extras.
BEND = 5
FORWARD = BEND + 2
STILL = FORWARD + 2  # the still arms' share (one gain)
WAVING = STILL + 1  # the waving arms' share (one gain)
WAVING_ELBOW = WAVING + 1  # the share of a waving arm's elbow bend that is the performer's (one gain)
KNEES = WAVING_ELBOW + 1  # the knees' bend part's share, then its pull
ELBOWS = KNEES + 2  # the elbows carried forward: the part's share, then its pull
LEAN = ELBOWS + 2  # the share of the way to the performer's lean (one gain)

# The least knee flexion (radians, of its low-pass) the knees' part divides by, and the range
# of the scale it gives: a low-pass near straight (a stiff-legged stride) would otherwise ask
# for any scale at all.
KNEE_LEVEL_FLOOR = math.radians(10.0)
KNEE_SCALE_RANGE = (0.5, 1.5)

# The forward part's low-pass (frames, of ``ArmPlaces.forward``): over a quarter second
# (``amplitude_tau``) 15 % of a 1 Hz walk's forward swing leaks into the mean and is carried
# against itself (the swing 15 % wider, ``tests/test_gait_amplitude.py``), and the carried
# hands shook: the multistyle model's jerk towards active 1.0988 -> 1.1011 at half of
# active's forward place (its held-out walks 1.052 -> 1.056; a constant carry left the
# locomotion's jerk as it was); over 1.5 s, 1.0990 (the model card, "Active carries its
# hands forward").
FORWARD_TAU = 45.0
# The lean part's low-pass (frames, of ``lean.spine_lean``): a walk's upper body sways across
# once a stride, and over ``amplitude_tau`` 15 % of a 1 Hz sway leaked into the mean and was
# carried against itself (``tests/test_gait_amplitude.py``); over FORWARD_TAU's 0.75 s, 1 %.
LEAN_TAU = 45.0


def _settled_filter(tau: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A triple pole over ``tau`` frames: lfilter's (b, a) and its state per unit of a held
    input (a low-pass started settled)."""
    b, a = triple_pole(tau)
    return b, a, lfilter_zi(b, a)[:, None]


def _pull_gains(points) -> tuple[tuple, tuple]:
    """``ContactSettings.elbow_bend``'s, ``arm_forward``'s, ``knee_bend``'s or
    ``elbow_forward``'s (input speed, share, degrees) -> the points of the part's share and of
    its pull (the share times the angle, in radians): two gains that rest at 0 standing and
    are low-passed apart, both linear in the share, so their ratio eases from one style's
    angle to another's."""
    return (tuple((speed, share) for speed, share, _ in points),
            tuple((speed, share * math.radians(degrees)) for speed, share, degrees in points))


class Parts(NamedTuple):
    """Which of ``GaitAmplitude``'s parts have work (``GaitAmplitude.active``)."""

    arms: bool
    hips: bool
    across: bool
    wave: bool  # a raised hand's sway, a wave's
    lift: bool  # ...a raise's
    bend: bool
    forward: bool
    still: bool
    knees: bool
    elbows: bool  # the elbows carried forward
    lean: bool  # the upper body's lean

    @property
    def crossing(self) -> bool:
        """The across part or a sway: the hands moved across the body (``_across_block``)."""
        return self.across or self.wave or self.lift


class _Gain:
    """One amplitude's gain: (speed, gain) points from (0, ``rest``), its g - rest low-passed."""

    def __init__(self, points, tau: float, most: float = math.inf, rest: float = 1.0):
        self.most = most  # the largest gain given
        self.rest = rest  # the gain standing, where nothing changes
        self.set_points(points)
        self.extra = TriplePole(tau)

    def set_points(self, points) -> None:
        points = sorted((float(a), float(b)) for a, b in points)
        self.on = bool(points)
        self._xs = [0.0] + [a for a, _ in points]
        self._ys = [self.rest] + [b for _, b in points]

    def at(self, speed: float) -> float:
        """The gain at ``speed``: ``np.interp`` written out on Python floats (per frame and
        performer in the daemon's tick, where np.interp's call was most of the recurrence)."""
        if not self.on:
            return self.rest
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
        # the across part's "gain" is the share of the output's own across swing kept
        self._across = _Gain(settings.arm_across, settings.pace_tau)
        self._wave = _Gain(settings.wave_sway, settings.pace_tau)
        self._raise = _Gain(settings.raise_sway, settings.pace_tau)
        # the elbows' bend: its share (0 standing) and that share times the bend asked for, in
        # radians, each low-passed, so a new style or a fade eases both (``_pull_gains``)
        self._bend_share, self._bend_pull = (_Gain(points, settings.pace_tau, rest=0.0)
                                             for points in _pull_gains(settings.elbow_bend))
        # the hands carried forward: the same pair of gains (``arm_forward``)
        self._forward_share, self._forward_pull = (_Gain(points, settings.pace_tau, rest=0.0)
                                                   for points in _pull_gains(settings.arm_forward))
        # the share of a still hanging arm's motion taken away (``still_arms``)
        self._still = _Gain(settings.still_arms, settings.pace_tau, rest=0.0)
        # ...and of a waving arm's (``waving_arms``)
        self._waving = _Gain(settings.waving_arms, settings.pace_tau, rest=0.0)
        # ...and the share of a waving arm's elbow bend that is the performer's (``waving_elbows``)
        self._waving_elbow = _Gain(settings.waving_elbows, settings.pace_tau, rest=0.0)
        # the knees' bend: the pair of gains of the elbows' (``knee_bend``)
        self._knee_share, self._knee_pull = (_Gain(points, settings.pace_tau, rest=0.0)
                                             for points in _pull_gains(settings.knee_bend))
        # the elbows carried forward: the pair of gains of the hands' (``elbow_forward``)
        self._elbow_share, self._elbow_pull = (_Gain(points, settings.pace_tau, rest=0.0)
                                               for points in _pull_gains(settings.elbow_forward))
        # the share of the way to the performer's lean (``performer_lean``)
        self._lean = _Gain(settings.performer_lean, settings.pace_tau, rest=0.0)
        # The low-passes' states, each (3, channels) once started: "arms" of the input arms
        # (``_arm_signal``, CHANNELS), "across" of the hands' places (``_across_signal``, 4),
        # "waving" of the input hands' across swing squared (2), "sway" of each hand's sway
        # gain - 1 (2, ``_sway_extra``), "bend" of the output elbows' flexion (2), "forward" of
        # the output hands' angles forward (2), "steps" of the input hands' squared steps (2),
        # "still" of their gates (2), "offset" of the arms' offsets from the input (14), and
        # "hold_across" of the input hands' places across (2), "hold_waving" of their swing
        # about it squared (2) and "waves" of the waving arms' gates (2) (``still``), "knees"
        # of the output knees' flexion (2), "elbows" of where the output upper arms point (6), and
        # "lean" of the input's and the output's lean (2, ``_lean_signal``)
        self._states: dict[str, np.ndarray | None] = {"arms": None, "across": None, "waving": None, "sway": None,
                                                      "bend": None, "forward": None, "steps": None, "still": None,
                                                      "offset": None, "hold_across": None, "hold_waving": None,
                                                      "waves": None, "knees": None, "elbows": None, "lean": None}
        # each low-pass's filter and settled state (``_settled_filter``), by key
        taus = dict.fromkeys(self._states, settings.amplitude_tau) | {"forward": FORWARD_TAU, "lean": LEAN_TAU}
        self._filters = {key: _settled_filter(tau) for key, tau in taus.items()}
        self._last: np.ndarray | None = None  # (ARMS, 4): the input arms' last quaternions, sign-aligned
        self._last_hands: np.ndarray | None = None  # (2, 3): the input hands' last places (``still``)
        self._height = TriplePole(settings.amplitude_tau)  # of the output root's height
        self._height_started = False
        self._speed = TriplePole(settings.pace_tau)
        self._previous: tuple | None = None  # the last input root's (x, z)
        self._last_step = 0.0  # the input's last horizontal step that was not a teleport
        self._first_step = True  # the stream's first step is yet to come
        # Whether the stream's first frame is shown (a live stream; ``FootLock.for_stream`` sets
        # it): its gains then start settled on that frame and ease into the first step's
        # rather than stepping into them after it. An offline clip's mirrored lead-in is not
        # shown, so its gains settle on its first step as the speed's does (see
        # ``_extras_of_frame``).
        self.first_frame_shown = False
        # arms, hips, across, wave, raise, the bend's share and pull, the forward part's, the
        # still and the waving arms', the waving elbows', the knees' share and pull, the
        # elbows' forward part's, the lean's: any gain off its rest so far (else the work is skipped)
        self._moving = [False] * len(self._gains)

    def set_points(self, arm_swing=(), hips_bob=(), arm_across=(), wave_sway=(), raise_sway=(),
                   elbow_bend=(), arm_forward=(), still_arms=(), waving_arms=(), waving_elbows=(),
                   knee_bend=(), elbow_forward=(), performer_lean=()) -> None:
        """New amplitudes (a new model, direction or style; () = the input's own), as
        (input speed cm/frame, gain) points (``elbow_bend``, ``arm_forward``, ``knee_bend``,
        ``elbow_forward``: (speed, share, degrees)); the gains move to them over the low-pass."""
        self._arms.set_points(arm_swing)
        self._hips.set_points(hips_bob)
        self._across.set_points(arm_across)
        self._wave.set_points(wave_sway)
        self._raise.set_points(raise_sway)
        self._still.set_points(still_arms)
        self._waving.set_points(waving_arms)
        self._waving_elbow.set_points(waving_elbows)
        self._lean.set_points(performer_lean)
        for gain, points in zip((self._bend_share, self._bend_pull, self._forward_share, self._forward_pull,
                                 self._knee_share, self._knee_pull, self._elbow_share, self._elbow_pull),
                                (*_pull_gains(elbow_bend), *_pull_gains(arm_forward), *_pull_gains(knee_bend),
                                 *_pull_gains(elbow_forward))):
            gain.set_points(points)

    def gains(self, speed: float) -> tuple[float, float]:
        """The arms' and the hips' gains at the input's speed ``speed`` (cm/frame): 1 at rest,
        straight lines through the points, the last point's gain beyond it; 1 without
        points; the arms' at most MAX_SWING_GAIN, the hips' at most MAX_BOB_GAIN."""
        return self._arms.at(speed), self._hips.at(speed)

    @property
    def active(self) -> Parts:
        """Whether the arms', the hips', the across, the wave's, the raise's, the elbows' bend's,
        the forward, the still arms', the knees', the elbows' forward and the lean parts have work
        (``_gains``' order, each pull part's two gains as one, the still and the waving arms'
        too): a gain set, or one still easing back to its rest. Their
        low-passes run only then (a session that never had a gain costs nothing but its
        speed), and start settled on the frame they start at."""
        on = [gain.on or moving for gain, moving in zip(self._gains, self._moving)]
        return Parts(*on[:BEND], on[BEND] or on[BEND + 1], on[FORWARD] or on[FORWARD + 1], on[STILL] or on[WAVING],
                     on[KNEES] or on[KNEES + 1], on[ELBOWS] or on[ELBOWS + 1], on[LEAN])

    @property
    def _gains(self) -> tuple[_Gain, ...]:
        return (self._arms, self._hips, self._across, self._wave, self._raise, self._bend_share, self._bend_pull,
                self._forward_share, self._forward_pull, self._still, self._waving, self._waving_elbow,
                self._knee_share, self._knee_pull, self._elbow_share, self._elbow_pull, self._lean)

    def apply(self, roots: np.ndarray, inputs: np.ndarray, outputs: np.ndarray, heights: np.ndarray,
              mix: np.ndarray | None = None, offsets: np.ndarray | None = None
              ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The next frames in order: input roots (n, 3), input and restyled rotations (n, J, 4),
        the output root's heights (n,), the share of the restyle shown (n,) (None: all of
        it) and the bone offsets (J, 3) (needed with ``arm_across``, the sways, ``arm_forward``,
        ``still_arms`` and ``performer_lean``) -> the outputs with the arms' swing scaled (a new array) and the new
        heights, each None where nothing changes."""
        n = len(roots)
        parts = self.active
        shown = [1.0] * n if mix is None else np.broadcast_to(mix, (n,)).tolist()
        extra = np.array([self._extras_of_frame(x, z, s) for (x, _, z), s in zip(np.asarray(roots).tolist(), shown)])
        swung = bobbed = None
        if parts.arms:
            inputs = np.asarray(inputs, np.float64)
            arms = _arm_signal(inputs, self._aligned_to(inputs[0]))
            self._last = arms[-1, :ARMS * 4].reshape(ARMS, 4)
            mean = self._low_pass("arms", arms)
            if self._moving[0]:
                swung = _swung(arms, mean, extra[:, 0], outputs)
        if parts.hips:
            heights = np.asarray(heights, np.float64)
            if not self._height_started:
                self._height_started = True
                self._height.settle_on(float(heights[0]))
            level = self._height.run(heights)
            if self._moving[1]:
                bobbed = level + (1.0 + extra[:, 1]) * (heights - level)
        if parts.crossing:
            moved = self._across_block(inputs, outputs if swung is None else swung, extra[:, 2:BEND], offsets)
            swung = swung if moved is None else moved
        if parts.bend:
            current = outputs if swung is None else swung
            mean = self._low_pass("bend", elbow_flexion(current))
            if self._moving[BEND] or self._moving[BEND + 1]:
                swung = _bent(current, mean, extra[:, BEND:FORWARD])
        if parts.forward:
            current = outputs if swung is None else swung
            places = arm_places(current, offsets)
            mean = self._low_pass("forward", places.forward())
            if self._moving[FORWARD] or self._moving[FORWARD + 1]:
                swung = _carried(current, mean, extra[:, FORWARD:STILL], places)
        if parts.elbows:
            current = outputs if swung is None else swung
            mean = self._low_pass("elbows", _elbow_signal(current))
            if self._moving[ELBOWS] or self._moving[ELBOWS + 1]:
                swung = _elbows_carried(current, mean, extra[:, ELBOWS:LEAN])
        if parts.still:
            inputs, current = np.asarray(inputs, np.float64), outputs if swung is None else swung
            hands = arm_places(inputs, offsets)
            first = np.full((1, 2, 3), np.nan) if self._last_hands is None else self._last_hands[None]
            self._last_hands = hands.hand[-1]
            offset, mean, weight = _still_signals(self._low_pass, inputs, current, hands,
                                                  np.concatenate([first, hands.hand[:-1]]), extra)
            if self._moving[STILL] or self._moving[WAVING]:
                swung = held(inputs, current, offset, mean, weight)
        if parts.knees:
            current = outputs if swung is None else swung
            mean = self._low_pass("knees", knee_flexion(current))
            if self._moving[KNEES] or self._moving[KNEES + 1]:
                swung = _straightened(current, mean, extra[:, KNEES:ELBOWS])
        if parts.lean:
            current = outputs if swung is None else swung
            mean = self._low_pass("lean", _lean_signal(np.asarray(inputs, np.float64), current, offsets))
            if self._moving[LEAN]:
                swung = _leaned_towards(current, mean, extra[:, LEAN])
        return swung, bobbed

    def _across_block(self, inputs, outputs, extra, offsets) -> np.ndarray | None:
        """``apply``'s across and sway parts on a block (``extra`` (n, 3): their gains - 1):
        the outputs with the hands moved, or None while neither has anything to move."""
        across, places = _across_signal(inputs, outputs, offsets)
        swing = across - self._low_pass("across", across)
        moved = _moved_across(swing, extra[:, 0], outputs, offsets, places) if self._moving[2] else None
        if self._swaying:
            sway = self._low_pass("sway", _sway_extra(self._low_pass("waving", swing[:, :2] ** 2), extra, places))
            if self._moving[3] or self._moving[4]:
                moved = _swayed(outputs if moved is None else moved, swing, sway, places)
        return moved

    @property
    def _swaying(self) -> bool:
        """Whether a sway part (the wave's, the raise's) has work: its low-passes run."""
        return any(gain.on or moving for gain, moving in zip((self._wave, self._raise), self._moving[3:]))

    def _low_pass(self, key: str, signal: np.ndarray) -> np.ndarray:
        """The low-pass ``key`` run over a block's ``signal`` (n, channels), started settled
        on its first frame."""
        b, a, settled = self._filters[key]
        if self._states[key] is None:
            self._states[key] = settled * signal[0]
        mean, self._states[key] = lfilter(b, a, signal, axis=0, zi=self._states[key])
        return mean

    def _aligned_to(self, first: np.ndarray) -> np.ndarray:
        """The upper arms' quaternions (ARMS, 4) the next frame's signs follow: the last
        frame's, or the first frame's own."""
        return first[SWING_INDEX] if self._last is None else self._last

    def _settle_gains(self, speed: float, shown: float) -> None:
        """Each gain's low-pass settled on its g - rest at ``speed``, times the share ``shown``."""
        for gain in self._gains:
            gain.extra.settle_on(shown * (gain.at(speed) - gain.rest))

    def _extras_of_frame(self, x: float, z: float, shown: float) -> tuple[float, float, float]:
        """One frame of the gains' recurrence on Python floats: each g - 1, low-passed. The
        speed is followed whether or not a gain is set, so a style set live starts from the
        performer's speed.

        As ``Pace``'s, the speed's low-pass starts settled on the stream's first step. So do
        the gains' where the stream's first frame is not shown (an offline clip's lead-in);
        where it is (``first_frame_shown``), they start settled on it, where no step is seen
        yet (standing), and ease from there. Settled on the first step there too, they stepped
        between the first two frames shown: a held-out turning walk that starts at 2.6 cm a
        frame took 28 % of the pair default's runs' elbow bend at once, and served live from
        its start the right hand jumped 11 cm, one frame's jerk 5.3x the input's largest
        (2026-12-08; the model card, "A stream's first step")."""
        first_frame = self._previous is None
        first_step = self._first_step and not first_frame
        px, pz = (x, z) if first_frame else self._previous
        self._previous = (x, z)
        step = math.hypot(x - px, z - pz)
        if step > TELEPORT_STEP:  # a looped clip or a tracker glitch (``Pace``): not a speed
            step = self._last_step
        self._last_step = step
        if first_step:
            self._first_step = False
            self._speed.settle_on(step)
            if not self.first_frame_shown:
                self._settle_gains(step, shown)
        speed = self._speed.step(step)
        if first_frame and self.first_frame_shown:
            self._settle_gains(speed, shown)
        extras = []
        for k, gain in enumerate(self._gains):
            if not (gain.on or self._moving[k]):
                extras.append(0.0)
                continue
            extra = gain.extra.step(shown * (gain.at(speed) - gain.rest))
            self._moving[k] = self._moving[k] or extra != 0.0
            extras.append(extra)
        return tuple(extras)



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


def _bent(outputs: np.ndarray, mean: np.ndarray, extra: np.ndarray) -> np.ndarray:
    """The outputs (n, J, 4) with each elbow bent the share ``extra[:, 0]`` of the way from its
    flexion's low-pass ``mean`` (n, 2, radians) to the bend asked for (``extra[:, 1]``, the
    share times it): the flexion's own swing about its mean stays, a hinge stays a hinge."""
    return add_elbow_flexion(outputs, extra[:, 1:2] - extra[:, 0:1] * mean)


def _straightened(outputs: np.ndarray, mean: np.ndarray, extra: np.ndarray) -> np.ndarray:
    """The outputs (n, J, 4) with each knee's flexion scaled so its low-pass ``mean`` (n, 2,
    radians) would go the share ``extra[:, 0]`` of the way to the bend asked for
    (``extra[:, 1]``, the share times it): scaled, not moved, so the stride's own swing of the
    knee grows or shrinks with it (a straighter-legged style swings its knees less), within
    KNEE_SCALE_RANGE."""
    level = np.maximum(mean, KNEE_LEVEL_FLOOR)
    scale = 1.0 + (extra[:, 1:2] - extra[:, 0:1] * level) / level
    return scale_knee_flexion(outputs, np.clip(scale, *KNEE_SCALE_RANGE))


def _carried(outputs: np.ndarray, mean: np.ndarray, extra: np.ndarray, places: ArmPlaces) -> np.ndarray:
    """The outputs (n, J, 4) with each hand carried forward the share ``extra[:, 0]`` of the
    way from its forward angle's low-pass ``mean`` (n, 2, radians) to the angle asked for
    (``extra[:, 1]``, the share times it), its swing about the mean kept; ``places``: the
    outputs' arm places."""
    return turn_upper_arms(outputs, places.parent, forward_turns(places, extra[:, 1:2] - extra[:, 0:1] * mean))


def _elbow_signal(outputs: np.ndarray) -> np.ndarray:
    """(n, 6): where each output upper arm points (``across.elbow_directions``), what the
    elbows' forward part low-passes: a direction's low-pass is continuous wherever the arm
    goes, its angle's is not."""
    return elbow_directions(outputs).reshape(len(outputs), 6)


def _elbows_carried(outputs: np.ndarray, mean: np.ndarray, extra: np.ndarray) -> np.ndarray:
    """The outputs (n, J, 4) with each upper arm turned the share ``extra[:, 0]`` of the way
    from its mean forward angle (of ``mean`` (n, 6), the low-pass of ``_elbow_signal``) to the
    angle asked for (``extra[:, 1]``, the share times it), its swing about the mean kept."""
    mean = mean.reshape(len(mean), 2, 3)
    mean = mean / np.linalg.norm(mean, axis=-1, keepdims=True)
    turns = elbow_forward_turns(mean, extra[:, 1:2] - extra[:, 0:1] * elbow_forward_angle(mean))
    out = np.array(outputs, np.float64)
    out[:, UPPER_ARM_INDEX] = rot.multiply(turns, out[:, UPPER_ARM_INDEX])
    return out


def _lean_signal(inputs: np.ndarray, outputs: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(n, 2) radians: the input's and the output's lean (``lean.spine_lean``), what the lean
    part low-passes."""
    return np.stack([spine_lean(inputs, offsets), spine_lean(outputs, offsets)], axis=1)


def _leaned_towards(outputs: np.ndarray, mean: np.ndarray, share: np.ndarray) -> np.ndarray:
    """The outputs (n, J, 4) with the spine turned the ``share`` (n,) of the way from the
    output's low-passed lean to the input's (``mean`` (n, 2), the low-pass of ``_lean_signal``):
    its own sway about its mean kept."""
    return leaned(outputs, share * (mean[:, 0] - mean[:, 1]))


def _across_signal(inputs: np.ndarray, outputs: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, ArmPlaces]:
    """(n, 4) cm: each hand's place across the body against its shoulder joint
    (``across.arm_places``), the input's (left, right) then the output's; and the output's
    arm places, which moving its hands reads again."""
    places = arm_places(outputs, offsets)
    return np.concatenate([arm_places(inputs, offsets).across(), places.across()], axis=1), places


def _sway_extra(waving: np.ndarray, extra: np.ndarray, places: ArmPlaces) -> np.ndarray:
    """(n, 2): each hand's sway gain - 1 before its low-pass: the wave's and the raise's
    (``extra`` (n, 3): the across, wave and raise gains - 1) mixed by how far the input hand
    waves (``waving``, the low-passed square of its across swing, over WAVING_GATE_CM), where
    the output hand is raised (over RAISED_GATE_CM). Low-passed after, because a hand comes down in a
    few frames while it still swings far across: the gate alone took 13 cm off a lowering
    hand in 3 frames (the multistyle model's raises towards active, one frame's jerk 21x the
    input's)."""
    if not extra[:, 1:].any():
        return np.zeros((len(extra), 2))
    wave = smoothstep(np.sqrt(waving), *WAVING_GATE_CM)
    gain = extra[:, 1:2] * wave + extra[:, 2:3] * (1.0 - wave)
    return gain * smoothstep(places.raised(), *RAISED_GATE_CM)


def _moved_across(swing: np.ndarray, extra: np.ndarray, outputs: np.ndarray, offsets: np.ndarray,
                  places: ArmPlaces) -> np.ndarray:
    """The outputs (n, J, 4) with each hand moved across by ``extra`` (n,) (the across gain's
    kept share - 1, low-passed: -1 where all is replaced) times the output's across swing
    less ACROSS_INPUT_SHARE of the input's, each about its low-pass (``swing`` (n, 4), the
    input's then the output's); ``places``: the outputs' arm places."""
    return move_across(outputs, offsets, extra[:, None] * (swing[:, 2:] - ACROSS_INPUT_SHARE * swing[:, :2]), places)


def _swayed(outputs: np.ndarray, swing: np.ndarray, sway: np.ndarray, places: ArmPlaces) -> np.ndarray:
    """The outputs (n, J, 4) with each hand moved across by ``sway`` (n, 2) (its sway gain -
    1, ``_sway_extra`` low-passed) times the output's across swing (``swing`` as
    ``_moved_across``'s), by ``sway_turns`` (to first order, and never further: a raise's
    lowering passes straight across); ``places``: the restyled arms' places."""
    return turn_upper_arms(outputs, places.parent, sway_turns(places, sway * swing[:, 2:]))


def _still_signals(low_pass, inputs: np.ndarray, outputs: np.ndarray, hands: ArmPlaces, before: np.ndarray,
                   extra: np.ndarray):
    """The still and the waving arms' low-passes on rows in order (a block of one stream, or one
    frame of each of many: ``low_pass(key, signal)`` runs either): ``hands``, the input's arm
    places, ``before`` (n, 2, 3), each row's input hands a frame earlier, and ``extra`` (n,
    extras), the rows' gains -> the arms' offsets from the input (n, 14), the offsets the hold
    aims at (their low-pass, a waving elbow's given back its share: ``held_aim``), and how far
    each arm is held (n, 2): its share times its gate, low-passed, where its hand hangs still
    or waves (the one excludes the other: a waving hand is raised, a still one not)."""
    steps = low_pass("steps", hand_steps_squared(hands.hand, before))
    raised = hands.raised()
    gate = low_pass("still", still_gate(steps, raised, RAISED_GATE_CM))
    across = hands.across()
    waving = low_pass("hold_waving", (across - low_pass("hold_across", across)) ** 2)
    waves = low_pass("waves", waving_gate(raised, waving, RAISED_GATE_CM))
    offset = offset_signal(inputs, outputs)
    still, waved = extra[:, STILL, None] * gate, extra[:, WAVING, None] * waves
    aim = held_aim(low_pass("offset", offset), still, waved, extra[:, WAVING_ELBOW, None])
    return offset, aim, np.minimum(still + waved, 1.0)


def amplitude_frames(amplitudes: list[GaitAmplitude], roots: np.ndarray, inputs: np.ndarray, outputs: np.ndarray,
                     heights: np.ndarray, shown: list[float], offsets: np.ndarray | None = None) -> None:
    """One frame of each of many streams (the daemon's tick): input roots (P, 3), input and
    restyled rotations (P, J, 4) and output root heights (P,) (``outputs`` and ``heights``
    changed in place), the share shown of each and the bone offsets, (J, 3) or each
    stream's (P, J, 3) (needed with ``arm_across``, the sways, ``arm_forward``, ``still_arms`` and
    ``performer_lean``); the same as each ``apply``, the arms of all in one vectorised pass (per
    stream, numpy's per-call cost would be most of it)."""
    active = [g.active for g in amplitudes]
    extra = np.array([g._extras_of_frame(x, z, f) for g, (x, _, z), f in zip(amplitudes, roots.tolist(), shown)])
    for k, (g, parts) in enumerate(zip(amplitudes, active)):
        if parts.hips:  # a scalar each: Python floats
            height = float(heights[k])
            if not g._height_started:
                g._height_started = True
                g._height.settle_on(height)
            level = g._height.step(height)
            if g._moving[1]:
                heights[k] = level + (1.0 + extra[k, 1]) * (height - level)
    _swing_frames(amplitudes, [k for k, parts in enumerate(active) if parts.arms], inputs, outputs, extra)
    _across_frames(amplitudes, [k for k, parts in enumerate(active) if parts.crossing], inputs, outputs, extra,
                   offsets)
    _pull_frames(amplitudes, [k for k, parts in enumerate(active) if parts.bend], outputs, extra, "bend",
                 elbow_flexion, BEND, _bent)
    _forward_frames(amplitudes, [k for k, parts in enumerate(active) if parts.forward], outputs, extra, offsets)
    _pull_frames(amplitudes, [k for k, parts in enumerate(active) if parts.elbows], outputs, extra, "elbows",
                 _elbow_signal, ELBOWS, _elbows_carried)
    _still_frames(amplitudes, [k for k, parts in enumerate(active) if parts.still], inputs, outputs, extra, offsets)
    _pull_frames(amplitudes, [k for k, parts in enumerate(active) if parts.knees], outputs, extra, "knees",
                 knee_flexion, KNEES, _straightened)
    _lean_frames(amplitudes, [k for k, parts in enumerate(active) if parts.lean], inputs, outputs, extra, offsets)


def _low_pass_streams(streams: list[GaitAmplitude], key: str, signal: np.ndarray) -> np.ndarray:
    """One frame of each stream's low-pass ``key`` in one step: ``signal`` (A, channels), a
    row per stream; each state starts settled on its stream's first frame. The streams share
    each key's tau (``amplitude_tau``, the forward part's ``FORWARD_TAU``), so one filter
    steps them all."""
    b, a, settled = streams[0]._filters[key]
    for g, row in zip(streams, signal):
        if g._states[key] is None:
            g._states[key] = settled * row
    state = np.stack([g._states[key] for g in streams], axis=1)  # (3, A, channels)
    mean, state = lfilter_one_step(b, a, signal, state)
    for k, g in enumerate(streams):
        g._states[key] = state[:, k]
    return mean


def _swing_frames(amplitudes, at, inputs, outputs, extra) -> None:
    """``amplitude_frames``' arms' swing for the streams ``at``."""
    if not at:
        return
    swings = [amplitudes[k] for k in at]
    frames = inputs[at]
    arms = _arm_signal(frames, np.stack([g._aligned_to(q) for g, q in zip(swings, frames)]))  # (A, CHANNELS)
    for g, arm in zip(swings, arms):
        g._last = arm[:ARMS * 4].reshape(ARMS, 4)
    mean = _low_pass_streams(swings, "arms", arms)
    rows = [i for i, g in enumerate(swings) if g._moving[0]]
    if rows:
        at_rows = [at[i] for i in rows]
        outputs[at_rows] = _swung(arms[rows], mean[rows], extra[at_rows, 0], outputs[at_rows])


def _across_frames(amplitudes, at, inputs, outputs, extra, offsets) -> None:
    """``amplitude_frames``' swing across and sways for the streams ``at``, after their arms' swing."""
    if not at:
        return
    rows_offsets = offsets if offsets.ndim == 2 else offsets[at]
    crossing = [amplitudes[k] for k in at]
    across, places = _across_signal(inputs[at], outputs[at], rows_offsets)  # (A, 4)
    swing = across - _low_pass_streams(crossing, "across", across)
    rows = [i for i, g in enumerate(crossing) if g._moving[2]]
    if rows:
        at_rows = [at[i] for i in rows]
        outputs[at_rows] = _moved_across(swing[rows], extra[at_rows, 2], outputs[at_rows],
                                         rows_offsets if rows_offsets.ndim == 2 else rows_offsets[rows],
                                         ArmPlaces(*(part[rows] for part in places)))
    swaying = [i for i, g in enumerate(crossing) if g._swaying]
    if swaying:  # their low-passes, and the move where a gain has been set
        streams, at_rows = [crossing[i] for i in swaying], [at[i] for i in swaying]
        their = ArmPlaces(*(part[swaying] for part in places))
        waving = _low_pass_streams(streams, "waving", swing[swaying, :2] ** 2)
        sway = _low_pass_streams(streams, "sway", _sway_extra(waving, extra[at_rows, 2:BEND], their))
        moving = [k for k, g in enumerate(streams) if g._moving[3] or g._moving[4]]
        if moving:
            rows = [at_rows[k] for k in moving]
            outputs[rows] = _swayed(outputs[rows], swing[swaying][moving], sway[moving],
                                    ArmPlaces(*(part[moving] for part in their)))


def _pull_frames(amplitudes, at, outputs, extra, key: str, flexion, gains: int, pulled) -> None:
    """``amplitude_frames``' elbows' bend (after the arms' swing and sways), elbows carried
    forward (after the hands carried) or knees' bend (after the arms) for the streams ``at``:
    the low-pass ``key`` of the ``flexion`` (or direction) of their outputs, and where the
    part's share or pull (the gains at ``gains`` and the next) has moved, the outputs
    ``pulled`` towards the style's."""
    if not at:
        return
    bending = [amplitudes[k] for k in at]
    mean = _low_pass_streams(bending, key, flexion(outputs[at]))
    rows = [i for i, g in enumerate(bending) if g._moving[gains] or g._moving[gains + 1]]
    if rows:
        at_rows = [at[i] for i in rows]
        outputs[at_rows] = pulled(outputs[at_rows], mean[rows], extra[at_rows, gains:gains + 2])


def _lean_frames(amplitudes, at, inputs, outputs, extra, offsets) -> None:
    """``amplitude_frames``' upper bodies leaned as their performers' for the streams ``at``, last."""
    if not at:
        return
    leaning = [amplitudes[k] for k in at]
    mean = _low_pass_streams(leaning, "lean", _lean_signal(inputs[at], outputs[at],
                                                           offsets if offsets.ndim == 2 else offsets[at]))
    rows = [i for i, g in enumerate(leaning) if g._moving[LEAN]]
    if rows:
        at_rows = [at[i] for i in rows]
        outputs[at_rows] = _leaned_towards(outputs[at_rows], mean[rows], extra[at_rows, LEAN])


def _forward_frames(amplitudes, at, outputs, extra, offsets) -> None:
    """``amplitude_frames``' hands carried forward for the streams ``at``, after their elbows' bend."""
    if not at:
        return
    carrying = [amplitudes[k] for k in at]
    places = arm_places(outputs[at], offsets if offsets.ndim == 2 else offsets[at])
    mean = _low_pass_streams(carrying, "forward", places.forward())
    rows = [i for i, g in enumerate(carrying) if g._moving[FORWARD] or g._moving[FORWARD + 1]]
    if rows:
        at_rows = [at[i] for i in rows]
        outputs[at_rows] = _carried(outputs[at_rows], mean[rows], extra[at_rows, FORWARD:STILL],
                                    ArmPlaces(*(part[rows] for part in places)))


def _still_frames(amplitudes, at, inputs, outputs, extra, offsets) -> None:
    """``amplitude_frames``' still arms for the streams ``at``, after their hands carried."""
    if not at:
        return
    streams, frames = [amplitudes[k] for k in at], inputs[at]
    hands = arm_places(frames, offsets if offsets.ndim == 2 else offsets[at])
    before = np.stack([np.full((2, 3), np.nan) if g._last_hands is None else g._last_hands for g in streams])
    for g, h in zip(streams, hands.hand):
        g._last_hands = h
    offset, mean, weight = _still_signals(lambda key, signal: _low_pass_streams(streams, key, signal), frames,
                                          outputs[at], hands, before, extra[at])
    rows = [i for i, g in enumerate(streams) if g._moving[STILL] or g._moving[WAVING]]
    if rows:
        at_rows = [at[i] for i in rows]
        outputs[at_rows] = held(frames[rows], outputs[at_rows], offset[rows], mean[rows], weight[rows])
