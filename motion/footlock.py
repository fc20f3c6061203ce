"""Planted feet stay planted: foot contacts of the input, and a two-bone leg IK that puts
each planted foot of the restyled output back where the input put it.

A restyle changes every bone's rotation, hips and legs included, while the root
trajectory is the input's (but for the pelvis height and the pace below): without a fix, a
foot the performer keeps still on the floor drifts with the restyled hips and knees (the
first shipped model slid planted feet by 1 cm per frame, 13x the input). This stage runs
after the seam blender on every output frame, live and offline alike (``SeamBlender`` ->
``FootLock.apply``), so ``restyle`` and ``serve`` send the same frames.

Contacts (``FootLock.push``, per input frame, in arrival order): a foot is planted when
its ankle or its ball is near the floor and nearly still, with hysteresis (a higher bar
to let go than to plant) so a noisy foot does not flicker. The floor is the lowest the
ball of the foot has been over the last ``floor_window`` frames (live sources do not say
where their floor is).

Lock (``FootLock.apply``, per output frame t): the leg weight w(t) rises to 1 over
``ramp`` frames before a contact and falls over ``release`` frames after it (a dilation of
the contacts by a smoothstepped triangle each side, which looks ``ramp`` frames ahead; the
release looks only back, so it may be longer: the stance's is 8). The daemon has ``delay``
frames of input beyond the frame it renders: a lock reads no further (its ``sight``), and
where that is short of the ramp (``--latency low``: one frame) the lock sets in as the
foot comes down to the floor (``approach``), before its contact is seen. Where w > 0 the
hip-knee-ankle chain is solved analytically: the ankle goes to the input's ankle (or, with
the stance kept, beside it) and the knee bends the way the restyled knee points off its own
hip-ankle line (a knee is a hinge that folds forward of its thigh, which decides where a
straight leg's own direction is round-off; the input's knee plane, which the lock took
before, undid a restyle's turned knees: 2.7 points less judged exhausted on the panel's
mean, 0.3 less action kept); within 1 mm of full stretch the reach is eased ("soft IK"), so a knee never
snaps as its target crosses it and the ankle falls short by at most 0.37 mm there; the
foot takes the input's world rotation (turned as restyled, with the stance) and the toes
the input's local one. The result is
slerped with the restyled leg by w. Only rotations change, so bone lengths are kept by
construction. The target follows the input's ankle at every frame (not a position frozen
at touch-down), so a mistaken contact costs nothing worse than the input's own leg for
a few frames.

Many performers at once (``FootLock.plan`` + ``solve_lock_jobs``): ``apply`` is a plan
(the lock's weights and floor for the frames) and a solve; the daemon plans each
performer's frame of a tick and solves them all in one vectorised pass, each frame with
its own performer's proportions (per-row bone offsets in ``leg_chain``/``solve_legs``),
each lock's pelvis and stance state advanced in order.

Floor (``_keep_above_floor``): a foot in the air whose ankle would go below its
standing height over the floor, or whose ball would go below the floor, is lifted onto it
by the same IK; near the floor, it keeps the input's own clearance too (a landing heel
is not set down early and dragged).

Pelvis height (``PelvisHeight``): the restyle bends knees and tilts the pelvis (an
exhausted stance is lower), but the root passes through, so with the hips at the input's
height the restyled planted feet float above the floor (measured on held-out normal clips
with the shipped model: median 4.4-5.9 cm in standing actions, 2.2-2.5 cm in walks) and
the IK could only put them down by straightening the legs again, undoing the style. So
the root is lowered (or raised) by the gap of the planted foot that floats most: that
foot then reaches its target with the restyled leg bend, the other bends further. The gap
is held through frames with no planted foot (a run's flight) and low-passed (a triple
pole, like the correction filter) so the hips never jump: fast while a foot is always
down, so the hips carry the restyled bend step by step, slower once the body has left the
floor, where each short contact asks for a new gap; it is capped so a wild output cannot
fold the legs. This moves the root, which the paper passes through: only
vertically, only by what the restyled legs themselves ask for.

Pace (``Pace``, ``--pace style``, the default): styles cover ground at their own speed,
and the judges see it (an exhausted run is slower). The root's horizontal steps are
scaled to the target style's pace; each foot carries its own share of the lag, frozen while
it is planted and caught up while it swings, so strides shorten and no planted foot slides.

Stance (``StanceOffset``, ``--feet stance``): a style stands differently (masculine feet
wide apart, feminine close together, knees and toes turned in or out), and a lock onto the
input's own ankles and knees undoes that: measured on held-out clips with the multi-style
model, windows judged masculine fell from 81 % unlocked to 11 % locked, feminine from 77 %
to 23 %, nearly all of it in the standing actions. With the stance kept, the target is the
input's ankle plus a horizontal offset (where the restyled foot stands beside the input's)
and the foot turns about the vertical as the restyled one; the knee keeps its restyled
plane. While a foot is free the offsets follow the restyled leg; while it is locked they
move at most ``stance_rate`` cm (``turn_rate`` degrees) a frame, so a planted foot lands
where the restyled leg put it and stays there (it may settle into a new stance, never
visibly slide). A foot's heading counts in proportion to its length on the floor: a foot
pointing down has none to follow. Through a stream's first fade-in from pass-through
(where it has one: ``words.BlendSettings.start_restyled``) the targets are taken at the
share the fade heads for, so a foot planted at the start stands in the restyled stance
from the first frame instead of sliding into it as the body fades in. Each model kind names
its lock (``FEET``, ``--feet auto``), and a checkpoint may name another (``train --feet``).
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from dataclasses import dataclass, replace

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy.signal import lfilter, lfilter_zi

from . import rotations as rot
from .errors import UserError
from .hinges import HINGES
from .humanoid import FORWARD, HUMANOID_BONES
from .skeleton import Skeleton
from .smoothing import triple_pole

LEGS = tuple(tuple(HUMANOID_BONES.index(f"{side}{b}") for b in ("UpperLeg", "LowerLeg", "Foot", "Toes"))
             for side in ("Left", "Right"))
LEG_INDEX = np.array(LEGS)  # (2 sides, 4 bones): both legs are processed as one batch
HIPS = HUMANOID_BONES.index("Hips")
FLOOR_MARGIN = 1.0  # cm above the floor from which a foot in the air is eased up (``_soft_floor``)
# cm along its thigh's forward axis a knee's own direction is leaned by where it is small
# (``knee_direction``): a straight leg's own direction is round-off, and a fold that
# followed it turned a knee 4 cm sideways in one frame (a held-out walk made youthful: a
# pop 9.5x the input's largest jerk)
KNEE_HINGE = 3.0
# cm short of full stretch from which the leg IK eases the reach (``_soft_reach``): a knee's
# height off its hip-ankle line grows as the square root of how far the ankle is inside
# reach, so a planted leg held straight bent by 1.3 cm in the frame its target came
# within reach (a standing VTuber's knee twitching, 4.5x the input's largest jerk). 1 mm
# took most of what 1 cm did (held-out clips made youthful with a pop over 1.5x the
# input's: 53 -> 17, 1 cm 12), and a leg the restyle left alone moves by 0.4 mm at most
# (1 cm: 3.7 mm, a visibly bent knee)
SOFT_REACH = 0.1
# cm of lift a foot needs before the floor step bends its leg fully (``_keep_above_floor``):
# a leg switched into the IK for a lift of a hundredth of a millimetre still moved its knee
# by the difference of the two solutions
FLOOR_LIFT_EASE = 0.5
# cm above its floor (the ankle: above its standing height) around which a foot in the air
# stops keeping the input's own clearance (``kept_clearance``, ``_keep_above_floor``). With
# the floor alone, the lowered pelvis set a landing heel on the floor up to 11 frames
# before the input's and dragged it there (a held-out walk made exhausted: the ankle at
# standing height moving 1.5-2 cm a frame where the input's was 1.3-2 cm up), and the
# output's skating read on its own contacts was 1.45x the input's in walks (real exhausted
# walks 0.95-1.03x the real normal ones'). Higher up the restyle lowers or lifts a swing freely.
CLEARANCE_BAND = 5.0
# cm a foot near the floor may go below the input's own (the soft edge's width is
# FLOOR_MARGIN: within half of it the clearance meets the input's with a smooth corner)
CLEARANCE_SLACK = 0.5
# The fastest pace against the performer's (``Pace``): a body ahead of its performer needs
# strides longer than the performer's from the same planted feet, and the planted leg
# stretched out behind the hips to full reach and popped its knee as the lock let go (the
# multistyle model made active, whose walks are 1.30x as fast: 7.3x the input's largest
# one-frame jerk, against 3.0x at the input's pace). So a style's pace only slows.
MAX_PACE_RATIO = 1.0
# cm a frame beyond which the input's root did not walk but jumped (30 m/s, three times a
# sprint): a looped clip starting over, a tracker losing its origin; the pace's lag is reset
TELEPORT_STEP = 50.0
# A foot's coming down to a contact (``approach``), for a lock that sees fewer frames ahead
# than its ramp: cm a frame from which a foot is not coming down (before the contact test
# plants it at 0.6, a walk's foot slows through 1.2-2.0 over its last six frames, a run's
# from 6-8 to under 3 in its last two; a swing moves 3-6), the most its lock weight moves a
# frame, and the frames read before the newest. Chosen on the training split (``approach``):
# 2.5, 3.5 and 6 cm/frame, 0.1-0.3 a frame over 4-10 frames were screened.
APPROACH_SPEED = 4.5
APPROACH_SLEW = 0.2
APPROACH_FRAMES = 5
# cm a free foot's ``Pace`` carry must reach before its leg is fully moved by it
# (``_carry_free_feet``), for the same reason
CARRY_EASE = 0.5


@dataclass(frozen=True)
class ContactSettings:
    """Thresholds in centimetres and centimetres per frame at 60 fps. Measured on the
    Bandai walks: a planted foot moves 0.03-0.08 cm/frame, a swinging one 3-6."""

    plant_height: float = 4.0  # ankle or ball at most this far above its floor height
    plant_speed: float = 0.6  # ...and its slower joint moving less than this
    release_height: float = 7.0  # let go above this
    release_speed: float = 1.5  # ...or faster than this
    floor_window: int = 240  # frames (4 s) over which the floor is the lowest ball height
    # Frames over which a lock blends in before and out after a contact. It looks this far
    # ahead: 4 fits serve's default (hop 4, delay 5) and restyle's (delay = hop = 4) alike,
    # so both lock the same frames; a stream of less delay foresees the rest (``approach``).
    ramp: int = 4
    # Frames over which a lock lets go after a contact (None: the lock's ramp). This side
    # needs no look-ahead, only the contacts already pushed, so it may be longer.
    release: int | None = None
    # Pelvis height: the low-pass time constant (frames; a triple pole, so the hips settle
    # over ~3 tau) and the most the hips move (cm). 0 tau: no adjustment. Measured on
    # held-out clips with the judge panel (models/checkpoints/MODEL_CARD.md): on the input's
    # ankles, 2 frames let the hips carry the restyled legs' bend step by step (the previous
    # pair default: 71.1 -> 81.9 % judged exhausted on the worst judge, walks 54 -> 78 %; timing
    # sync 0.818 -> 0.815, pops and slide unchanged); 1 frame read 83.0 % but popped (2.6x
    # the input's largest jerk). The stance keeps 8 (``FEET``).
    pelvis_tau: float = 2.0
    pelvis_cap: float = 12.0
    # ...and the time constant once the body has left the floor (no foot locked: 11-24 % of
    # a held-out run's frames, none of any other action's) within the last flight_memory
    # frames (0.5 s, a run's stride and more). A run plants each foot for a few frames
    # between flights, and hips that drop by each new contact's gap within 2 frames snapped
    # the knee (a model trained with --lambda-action 0.25: 2.52x the input's largest jerk
    # with 2, 1.19x with 8, on the same held-out run).
    pelvis_flight_tau: float = 8.0
    flight_memory: int = 30
    # Stance: the most a planted foot stands beside the input's (cm; 0: on the input's
    # own ankle) and how fast the offset may move while
    # the foot is locked (cm/frame; a planted input foot moves 0.03-0.08, so this adds at
    # most a third to its slide).
    stance_cap: float = 0.0
    stance_rate: float = 0.01
    # ...and the foot's turn about the vertical against the input's (toes out or in):
    # at most this many degrees, moving at most this fast while locked (0.04 degrees a
    # frame moves the ball of a 15 cm foot 0.01 cm).
    turn_cap: float = 30.0
    turn_rate: float = 0.04
    # A foot's heading is only as sure as its length on the floor (ankle to ball, cm): a
    # foot pointing down (toe-off, a swing about to land) has none, and following it turned
    # a landing foot by 54 degrees in one frame (a held-out walk). The turn follows a foot
    # fully from turn_sure cm on the floor, not at all below turn_unsure, in between in part.
    turn_unsure: float = 2.0
    turn_sure: float = 6.0
    # Pace (``Pace``): the output covers ground at the style's speed. Points (input speed,
    # output speed) of the root's horizontal travel in cm/frame, joined by straight lines
    # from (0, 0) and extended at the last point's ratio; () = the input's own pace (the
    # root's horizontal path passes through). The input's speed is low-passed over
    # pace_tau frames (about a stride), so a stride's own rhythm does not change the ratio.
    pace: tuple[tuple[float, float], ...] = ()
    pace_tau: float = 15.0
    # ...and the share per frame by which a foot in the air catches up with the body's
    # shift after its lock lets go (a planted foot keeps the shift it landed with).
    carry_rate: float = 0.15


# Where planted feet go (``--feet``). "input": on the input's own ankles, turned as the
# input's; a pair model keeps it unless its checkpoint names another. "stance": beside
# them, where the restyled legs stand, turned as restyled (the knees bend as restyled in
# both). The multi-style model reads most as its targets so (78.5 % on the judges' mean
# over six against 57.8 %), but for elderly and exhausted (its ``feet_of_style``). For the
# pair default "input" reads better since its hips follow within 2 frames (88.1 % against
# 75.4 % on the judges' mean, action 89.5 against 86.8 %), and while planted the stance
# creeps 0.011-0.012 cm a frame in the standing actions against the input's 0.005
# (2.2-2.6x). The stance's hips settle slower (8 frames): with 2 the
# multistyle model read feminine 79.6 -> 55.5 % (its walks 91 -> 2 %) and popped more in
# five styles of six, though active, elderly, exhausted and masculine gained 7-16 points.
# "auto", the default, takes the model's own (``Restyler.feet``; figures in
# models/checkpoints/MODEL_CARD.md).
# The stance's cap: a foot's offset is taken where its lock starts to blend in, ``ramp``
# frames before touch-down, while the restyled foot still swings, so a large one is mostly
# swing: with 15 cm the multistyle model's knees popped 3.1-4.0x the input's largest jerk in
# active, feminine, masculine and youthful walks and runs; 8 cm: 1.95-3.11x, every style read
# as its target within a point of 15 cm's (5 cm: feminine -2.0). Following the restyled foot
# until full contact instead popped more (6.6x, a feminine run): the offset then stops dead.
# The stance lets go over 8 frames: its planted foot stands up to the cap from the input's
# while the restyled swing foot is elsewhere again by lift-off, and over 4 frames the foot
# jumped that gap (the multistyle model's held-out active walks: a toe's one-frame jerk 5x
# the input's; active's jerk ratio 1.132 over held-out takes, 1.093 over 8 frames, youthful
# 1.081 -> 1.056; for 4 points of active's style on the worst conv judge, the others within a
# point or better: the model card's "The stance lets go over 8 frames"). The input lock keeps
# 4: with 8 the pair default read exhausted 0.8 points less on its worst conv judge, where
# it stands at the bar (its jerk was 1.008 already).
FEET = {"input": ContactSettings(), "stance": ContactSettings(stance_cap=8.0, pelvis_tau=8.0, release=8)}
AUTO_FEET = "auto"  # the model's own choice (its ``feet``), else "input"


# ``--pace``: "style", the output covers ground at the target style's pace (``Pace``; the
# restyler's ``pace()`` points, where it has them), or "input", the performer's own (the
# root's horizontal path passes through). Style is the default: keeping the performer's
# pace, the pair default read exhausted in 86.1 % of held-out windows on the worst judge,
# runs 27 %; at the style's pace 92.1 %, runs 82 % (models/checkpoints/MODEL_CARD.md).
PACE_CHOICES = ("style", "input")


def check_feet(name: str) -> str:
    """A ``--feet`` name, or one sentence naming the known ones (before any work)."""
    if name not in (AUTO_FEET, *FEET):
        raise UserError(f"--feet {name!r} is not known; use one of {', '.join((AUTO_FEET, *FEET))}")
    return name


def check_pace(name: str) -> str:
    """A ``--pace`` name, or one sentence naming the known ones (before any work)."""
    if name not in PACE_CHOICES:
        raise UserError(f"--pace {name!r} is not known; use one of {', '.join(PACE_CHOICES)}")
    return name


def pace_of(restyler, pace: str = "style", weights=None) -> tuple:
    """``ContactSettings.pace`` for ``--pace NAME`` with ``restyler`` (towards the style mix
    ``weights``, where it takes one): () for the input's pace or a restyler without one."""
    if pace != "style" or not hasattr(restyler, "pace"):
        return ()
    return tuple(restyler.pace(weights))


def feet_for(name: str, restyler=None, pace: str = "style") -> ContactSettings:
    """``--feet NAME`` and ``--pace`` (checked beforehand) for ``restyler``: "auto" takes
    the model's own lock."""
    if name == AUTO_FEET:
        name = getattr(restyler, "feet", "input")
    points = pace_of(restyler, pace)
    return replace(FEET[name], pace=points) if points else FEET[name]


class _TriplePole:
    """``smoothing.triple_pole`` over a scalar signal, its state carried from call to call."""

    def __init__(self, tau: float):
        self._b, self._a = triple_pole(tau)
        self._coefficients = (float(self._b[0]), *self._a[1:].tolist())  # b0, a1, a2, a3 for ``step``
        self._state = [0.0, 0.0, 0.0]
        self._settled = lfilter_zi(self._b, self._a).tolist()  # the state per unit of a held input

    def settle_on(self, x: float) -> None:
        """The state of a filter that has held ``x`` forever: its next output is ``x``."""
        self._state = [z * float(x) for z in self._settled]

    def run(self, x: np.ndarray) -> np.ndarray:
        y, state = lfilter(self._b, self._a, x, zi=np.asarray(self._state))
        self._state = state.tolist()
        return y

    def step(self, x: float) -> float:
        """``run`` of one value on Python floats (the daemon's case; scipy's lfilter costs
        ~50 us a call): the same recursion, in lfilter's transposed direct form II."""
        (z0, z1, z2), (b0, a1, a2, a3) = self._state, self._coefficients
        y = b0 * x + z0
        self._state = [z1 - a1 * y, z2 - a2 * y, -a3 * y]
        return y


class PelvisHeight:
    """The vertical root offset of the output (see the module docstring), causal, with its
    state carried from block to block: a clip at once and a stream a frame at a time give
    the same offsets.

    Two low-passes of the held gap run side by side: ``tau`` while a foot is always down
    (standing, walking) and ``flight_tau`` once the body has left the floor within the last
    ``flight_memory`` frames (a run, a jump), crossfaded by a weight that is itself
    low-passed over ``flight_tau`` so the switch never steps. Without a ``flight_memory``
    (or with ``flight_tau`` = ``tau``) it is the one low-pass."""

    def __init__(self, tau: float, cap: float, flight_tau: float | None = None, flight_memory: int = 0):
        self.tau, self.cap = float(tau), float(cap)
        self.flight_tau = self.tau if flight_tau is None else float(flight_tau)
        self.flight_memory = int(flight_memory)
        self._ground, self._flight = _TriplePole(self.tau), _TriplePole(self.flight_tau)
        self._weight = _TriplePole(self.flight_tau)  # of the flight low-pass, 0..1
        self._held = 0.0  # the last gap seen with a foot planted
        self._since_flight = self.flight_memory  # frames since the last with no foot planted

    def drops(self, gaps: np.ndarray, planted: np.ndarray) -> np.ndarray:
        """Per frame in order: the output ankles' height over the input's (n, 2) and which
        feet are being locked (n, 2) -> how far to lower the root (n,), negative = raise."""
        if len(gaps) == 1:
            return np.array([self.drop_of_one_frame(gaps[0].tolist(), planted[0].tolist())])
        if self.tau <= 0:
            return np.zeros(len(gaps))
        wanted = np.where(planted, gaps, -np.inf).max(axis=1)
        seen = np.isfinite(wanted)
        # Hold the last planted gap through frames with no foot down.
        last = np.maximum.accumulate(np.where(seen, np.arange(len(gaps)), -1))
        held = np.where(last >= 0, wanted[np.maximum(last, 0)], self._held)
        if seen.any():
            self._held = float(wanted[seen][-1])
        held = np.clip(held, -self.cap, self.cap)
        # Frames since the last one with no foot planted, carried over from the last block.
        index = np.arange(len(gaps))
        since = index - np.maximum.accumulate(np.where(seen, -1 - self._since_flight, index))
        self._since_flight = int(min(since[-1], self.flight_memory))
        weight = self._weight.run((since < self.flight_memory).astype(float))
        return (1.0 - weight) * self._ground.run(held) + weight * self._flight.run(held)

    def drop_of_one_frame(self, gaps: list, planted: list) -> float:
        """``drops`` for one frame on Python floats (the daemon's case): two gaps, two flags."""
        if self.tau <= 0:
            return 0.0
        down = [g for g, p in zip(gaps, planted) if p]
        if down:
            self._held = max(down)
        self._since_flight = min(self._since_flight + 1, self.flight_memory) if down else 0
        x = min(max(self._held, -self.cap), self.cap)
        weight = self._weight.step(float(self._since_flight < self.flight_memory))
        return (1.0 - weight) * self._ground.step(x) + weight * self._flight.step(x)


class StanceOffset:
    """Where each locked foot stands against the input's (see the module docstring): its
    ankle's horizontal offset (x, z, cm) and its turn about the vertical (radians); state
    carried from block to block like ``PelvisHeight``."""

    def __init__(self, settings: ContactSettings):
        self.cap, self.rate = settings.stance_cap, settings.stance_rate
        self.turn_cap, self.turn_rate = np.radians(settings.turn_cap), np.radians(settings.turn_rate)
        self.turn_unsure, self.turn_sure = settings.turn_unsure, settings.turn_sure
        self._offset: list | None = None  # [[x, z, turn], [x, z, turn]] of the last frame
        # Before this frame the offsets follow the restyle freely: an offline clip's mirrored
        # lead-in, which is not shown (0 for a stream).
        self.free_until = 0
        # A stream that fades the restyle in from pass-through (``start_restyled=False``)
        # shows its stance only in part until this frame (``first_fade_end``; 0 for a stream
        # restyled from its first frame). Its targets are then taken at the share the fade
        # heads for (``aim``, the stream's intensity): the restyled offset over the share shown
        # so far, low-passed as the correction is (``fade_tau``). So a planted foot stands in
        # the restyled stance from the first frame while the body fades in. Following the
        # fading stance instead slid planted feet 3.2-4.8x the input's over held-out takes
        # played live with the multi-style model at the default hop (1.2-1.3x this way, for
        # 4-8 points of active, masculine and youthful's style reading: the model card's
        # "The stance through a stream's fade-in"); holding the input's stance kept a
        # standing performer's feet there for good (width 15.1 cm against the input's 15.2
        # and the restyle's 7-15, a feminine raise-up-both-hands take).
        self.fade_until = 0
        self.aim = 1.0
        self._shown: _TriplePole | None = None  # the shown share's low-pass (``for_fade``)
        self._fading = False  # the first fade's first frame seen

    def for_fade(self, fade_until: int, fade_tau: float) -> None:
        """A stream's first fade from pass-through ends at frame ``fade_until``, its correction
        low-passed over ``fade_tau`` frames (see ``fade_until`` above)."""
        self.fade_until = int(fade_until)
        self._shown = _TriplePole(fade_tau) if fade_tau > 0 else None

    def track(self, t0: int, own: tuple, restyled: tuple, locked: np.ndarray,
              shown: np.ndarray | None = None) -> np.ndarray | None:
        """Frames t0 .. t0+n-1 in order: the input's and the restyled (ankle, ball)
        positions, each (n, 2, 3), which feet are locked (n, 2) and the share of the
        restyle shown in each frame (n,; None: all of it) -> the lock targets' offsets from
        the input's feet (n, 2, 3: x, z in cm and the turn in radians), or None when off."""
        if self.cap <= 0:
            return None
        wanted, sure = stance_targets(own, restyled, self.cap, self.turn_cap, self.turn_unsure, self.turn_sure)
        shown = [1.0] * len(wanted) if shown is None else np.broadcast_to(shown, (len(wanted),)).tolist()
        return np.array(self.follow(t0, wanted.tolist(), locked.tolist(), sure.tolist(), shown))

    def follow(self, t0: int, wanted: list, locked: list, sure: list, shown: list) -> list:
        """``track``'s recurrence over frames t0 .. t0+n-1 on Python floats: the targets
        (``stance_targets``), which feet are locked, how sure each turn is and the share of
        the restyle shown, per frame as nested lists -> the offsets, the same nesting (new
        lists). A rate limit is a recurrence; on floats because the daemon runs it one frame
        at a time per performer (numpy's per-call cost would be most of it)."""
        if t0 < self.fade_until:
            wanted = [self._at_aim(t0 + i, frame, share) for i, (frame, share) in enumerate(zip(wanted, shown))]
        current = self._offset if self._offset is not None else wanted[0]
        out = []
        for i, (frame, held, certainty) in enumerate(zip(wanted, locked, sure)):
            settled = t0 + i >= self.free_until
            moved = []
            for foot in (0, 1):
                (x, z, turn), (wx, wz, wturn) = current[foot], frame[foot]
                dx, dz, dturn = wx - x, wz - z, (wturn - turn) * certainty[foot]
                if held[foot] and settled:
                    step = (dx * dx + dz * dz) ** 0.5
                    if step > self.rate:
                        dx, dz = dx * self.rate / step, dz * self.rate / step
                    dturn = min(max(dturn, -self.turn_rate), self.turn_rate)
                moved.append([x + dx, z + dz, turn + dturn])
            current = moved
            out.append(current)
        self._offset = current
        return out

    def _at_aim(self, t: int, frame: list, share: float) -> list:
        """Frame t's targets [[x, z, turn], ...] of a restyle shown at ``share`` -> at the
        share the stream's first fade heads for (``fade_until``), within the caps."""
        if self._shown is not None:
            if not self._fading:  # the stream's first frame: the low-pass starts settled, as the correction's
                self._shown.settle_on(share)
            share = self._shown.step(share)
        self._fading = True
        if t >= self.fade_until or share < 1e-3 or share >= self.aim:  # (nothing shown: nothing to scale)
            return frame
        scale, out = self.aim / share, []
        for x, z, turn in frame:
            length = (x * x + z * z) ** 0.5
            fit = min(scale, self.cap / length) if length > 0 else scale
            out.append([x * fit, z * fit, min(max(turn * scale, -self.turn_cap), self.turn_cap)])
        return out


def stance_targets(own: tuple, restyled: tuple, cap, turn_cap, turn_unsure, turn_sure) -> tuple:
    """Where ``StanceOffset`` wants each locked foot: the input's and the restyled (ankle,
    ball) positions, each (n, 2, 3), and the settings (numbers, or one per row shaped to
    broadcast: (n, 1, 1) for the caps, (n, 1) for the turn's certainty band) -> the wanted
    offsets (n, 2, 3: x, z in cm within ``cap``, the turn in radians within ``turn_cap``)
    and how sure each turn is (n, 2: 0 below ``turn_unsure`` cm of foot on the floor, 1
    from ``turn_sure``)."""
    foot_out, foot_in = restyled[1] - restyled[0], own[1] - own[0]  # ankle to ball
    turn = _heading(foot_out) - _heading(foot_in)
    turn = (turn + np.pi) % (2 * np.pi) - np.pi
    on_floor = np.minimum(_floor_length(foot_out), _floor_length(foot_in))
    sure = np.clip((on_floor - turn_unsure) / (turn_sure - turn_unsure), 0.0, 1.0)
    wanted = np.concatenate([(restyled[0] - own[0])[..., [0, 2]], turn[..., None]], axis=-1)
    length = np.linalg.norm(wanted[..., :2], axis=-1, keepdims=True)
    wanted = np.concatenate([wanted[..., :2] * np.minimum(1.0, cap / np.maximum(length, 1e-9)),
                             np.clip(wanted[..., 2:], -turn_cap, turn_cap)], axis=-1)
    return wanted, sure


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
    its own shift: frozen while its lock holds it (the foot stays where it landed),
    following the body's step while free and catching up with it at ``carry_rate`` a
    frame, in between in proportion to the lock weight, so it moves smoothly through the
    ramps. The foot lock puts a planted foot on the input's ankle less its shift, and a
    free foot where the restyled leg puts it, moved by how far its shift lags the body's
    (``_carry_free_feet``): shorter strides at the same cadence."""

    def __init__(self, settings: ContactSettings):
        self.set_points(settings.pace)
        self.rate = float(settings.carry_rate)
        self._speed = _TriplePole(settings.pace_tau)
        self._slowdown = _TriplePole(settings.pace_tau)
        self._previous: tuple | None = None  # the last input root's (x, z)
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

    def track(self, roots: np.ndarray, weights: np.ndarray, mix: np.ndarray | None = None):
        """The next frames in order: input roots (n, 3), the lock weights (n, 2) and the share
        of the restyle shown (n,) (None: all of it) -> the body's shift (n, 2: x, z) and each
        foot's (n, 2, 2), to take off the input's travel; None while there is none. A
        recurrence on Python floats (``track_one_frame`` is the daemon's frame)."""
        if not (self.on or self._moving):
            self._previous = tuple(np.asarray(roots)[-1, [0, 2]].tolist())
            return None
        self._moving = True
        n = len(roots)
        mix = [1.0] * n if mix is None else np.broadcast_to(mix, (n,)).tolist()
        body, feet = np.empty((n, 2)), np.empty((n, 2, 2))
        for i, ((x, _, z), (left, right), shown) in enumerate(zip(roots.tolist(), weights.tolist(), mix)):
            body[i], feet[i] = self._step(x, z, left, right, shown)
        return body, feet

    def track_one_frame(self, x: float, z: float, left: float, right: float, shown: float):
        """``track`` of one frame on Python floats (the daemon's case): the input root's x and
        z, the two lock weights and the share shown -> the body's shift [x, z] and each
        foot's [[x, z], [x, z]] (new lists), or None while there is none."""
        if not (self.on or self._moving):
            self._previous = (x, z)
            return None
        self._moving = True
        return self._step(x, z, left, right, shown)

    def _step(self, x: float, z: float, left: float, right: float, shown: float) -> tuple[list, list]:
        """One frame of the recurrence (see ``track``); the new shifts, as new lists."""
        (sx, sz), rate = self._shift, self.rate
        first_step = self._first_step and self._previous is not None
        px, pz = (x, z) if self._previous is None else self._previous
        self._previous = (x, z)
        dx, dz = x - px, z - pz
        step = math.hypot(dx, dz)
        feet = self._feet
        if step > TELEPORT_STEP:
            # A looped clip or a tracker glitch: the avatar goes with its performer and
            # the lag starts again from nothing (the step would otherwise be scaled and
            # leave the feet a stride's worth of metres behind the body).
            sx = sz = 0.0
            feet = [[0.0, 0.0], [0.0, 0.0]]
            dx = dz = 0.0
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
        step_x, step_z = slow * dx, slow * dz
        self._feet = [[fx + (1.0 - w) * (step_x + rate * (sx - fx)), fz + (1.0 - w) * (step_z + rate * (sz - fz))]
                      for (fx, fz), w in zip(feet, (left, right))]
        self._shift = [sx + step_x, sz + step_z]
        return self._shift, self._feet


def leg_chain(roots: np.ndarray, rotations: np.ndarray, offsets: np.ndarray):
    """Forward kinematics of the Hips and both legs only, vectorised over frames.

    roots (n, 3), rotations (n, J, 4), offsets (J, 3) or per row (n, J, 3) (frames of
    several performers in one call) -> world positions (n, 2, 4, 3) of each leg's joints
    (hip socket, knee, ankle, ball of the foot), world rotations (n, 2, 4, 4) of UpperLeg,
    LowerLeg, Foot and Toes, and the Hips' world rotation (n, 4)."""
    hips = rotations[:, HIPS]
    n = len(roots)
    pos = np.empty((n, 2, 4, 3))
    world = np.empty((n, 2, 4, 4))
    offs = offsets[..., LEG_INDEX, :]  # (2, 4, 3) or (n, 2, 4, 3)
    local = rotations[:, LEG_INDEX]  # (n, 2, 4, 4)
    parent_rot = np.broadcast_to(hips[:, None], (n, 2, 4))
    parent_pos = np.broadcast_to(roots[:, None], (n, 2, 3))
    for k in range(4):
        pos[:, :, k] = parent_pos = parent_pos + rot.apply(parent_rot, offs[..., k, :])
        world[:, :, k] = parent_rot = rot.multiply(parent_rot, local[:, :, k])
    return pos, world, hips


def _shortest_arc(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Vectorised smallest rotation turning unit vectors a onto b (..., 3) -> (..., 4).
    Leg corrections are far from half turns, where this form would lose its axis."""
    q = np.concatenate([rot.cross(a, b), 1.0 + np.sum(a * b, axis=-1, keepdims=True)], axis=-1)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


# The axis of the thigh's frame a knee folds about: both knees share it (``hinges.HINGES``).
(_KNEE_AXIS,) = {tuple(np.eye(3)[h.flexion]) for h in HINGES if h.bone.endswith("LowerLeg")}
_KNEE_AXIS = np.array(_KNEE_AXIS)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def knee_direction(legs: np.ndarray, world: np.ndarray) -> np.ndarray:
    """Leg joint positions and world rotations (..., 2, 4, 3) and (..., 2, 4, 4) as
    ``leg_chain``'s -> the way each knee folds (..., 2, 3): where it points off its own
    hip-ankle line (the plane it bends in, whatever the ankle's target), leaned forward of
    its thigh where that is small. A knee is a hinge that folds forward of its thigh: in
    the retargeted data the two agree to 0.2 degrees wherever the knee is 2 cm or more off
    its line, in restyled legs bent 3 cm or more to 1-2 degrees (median), but a straight
    or overstraightened leg's own direction is round-off (restyled knees within 1 cm of
    their line: 25-54 degrees off the hinge, median). So a backward part is dropped and
    KNEE_HINGE cm along the thigh's forward axis added, fading as the knee's own offset
    grows past it (a clearly bent knee out of its hinge keeps its own plane)."""
    socket, knee, ankle = legs[..., 0, :], legs[..., 1, :], legs[..., 2, :]
    line = _unit(ankle - socket)

    def off_line(v):
        return v - np.sum(v * line, axis=-1, keepdims=True) * line

    own = off_line(knee - socket)
    ahead = _unit(off_line(rot.apply(world[..., 0, :], FORWARD)))
    forward = np.sum(own * ahead, axis=-1, keepdims=True)
    size = np.linalg.norm(own, axis=-1, keepdims=True)
    return own + (np.maximum(-forward, 0.0) + KNEE_HINGE / (1.0 + (size / KNEE_HINGE) ** 2)) * ahead


def _soft_reach(dist: np.ndarray, reach) -> np.ndarray:
    """Hip-to-target distances -> the distances the leg IK solves for: unchanged up to
    SOFT_REACH short of full ``reach``, then approaching it exponentially ("soft IK"), so
    the knee moves smoothly as a target crosses full stretch. The ankle falls short of a
    target there by at most SOFT_REACH / e (0.37 mm) at full stretch, more beyond it."""
    soft = reach - SOFT_REACH
    eased = soft + SOFT_REACH * (1.0 - np.exp(-np.maximum(dist - soft, 0.0) / SOFT_REACH))
    return np.where(dist > soft, eased, dist)


def solve_legs(roots: np.ndarray, rotations: np.ndarray, offsets: np.ndarray, ankle_target: np.ndarray,
               foot_world: np.ndarray, chain: tuple | None = None) -> np.ndarray:
    """Two-bone IK of both legs: local rotations (n, 2, 3, 4) of UpperLeg, LowerLeg and
    Foot that put each ankle on ``ankle_target`` (n, 2, 3) (as near as the leg reaches,
    eased within SOFT_REACH of full stretch), bend each knee the way it folds in
    ``rotations`` (``knee_direction``) and give the foot the world rotation ``foot_world``
    (n, 2, 4); the hips are those of ``rotations``; ``offsets`` as ``leg_chain``'s; ``chain``:
    ``leg_chain``'s result for these, where the caller has it already."""
    pos, world, hips = leg_chain(roots, rotations, offsets) if chain is None else chain
    thigh = np.linalg.norm(offsets[..., LEG_INDEX[:, 1], :], axis=-1)  # (2,) or (n, 2): socket to knee
    shin = np.linalg.norm(offsets[..., LEG_INDEX[:, 2], :], axis=-1)  # knee to ankle
    socket, knee = pos[:, :, 0], pos[:, :, 1]
    to_target = ankle_target - socket
    dist = _soft_reach(np.linalg.norm(to_target, axis=-1), thigh + shin)
    dist = np.clip(dist, np.abs(thigh - shin) + 1e-6, thigh + shin - 1e-6)
    axis = _unit(to_target)
    along = (thigh ** 2 - shin ** 2 + dist ** 2) / (2 * dist)  # law of cosines
    height = np.sqrt(np.maximum(thigh ** 2 - along ** 2, 0.0))
    # The knee's direction off its own hip-ankle line, not the knee's point off the line to
    # the target: a planted foot held far behind a leg that swung on put the restyled knee
    # on that line, and the bend flipped from front to back in one frame (36 cm, a held-out
    # walk). Where the ankle already is, the two are the same.
    # A straight leg asked to bend has no direction of its own (round-off flipped a knee
    # lifted off the floor by 5 cm and back in one frame): the hinge in ``knee_direction``
    # folds it forward of its thigh.
    pole = knee_direction(pos, world)
    bend = _unit(pole - np.sum(pole * axis, axis=-1, keepdims=True) * axis)
    new_knee = socket + along[..., None] * axis + height[..., None] * bend
    new_ankle = socket + dist[..., None] * axis
    # Swing the thigh onto its new direction from where it points now (keeps its twist),
    # then turn it about itself so the knee's hinge axis (``hinges``: the thigh frame's X)
    # is the normal of the plane the leg bends in, and fold the shin about that axis
    # alone: a knee is a hinge. Swinging the shin by its own shortest arc instead left
    # the knees 2.1 degrees off their hinge at the 99th percentile of held-out frames (the
    # input's 0.6), sideways bends and twists no performer's knee makes.
    thigh_dir = _unit(new_knee - socket)
    upper_world = rot.multiply(_shortest_arc(_unit(knee - socket), thigh_dir), world[:, :, 0])
    hinge_now = rot.apply(upper_world, _KNEE_AXIS)
    normal = _unit(rot.cross(bend, axis))  # the fold's axis: a bent knee's shin goes back
    turn = np.arctan2(np.sum(thigh_dir * rot.cross(hinge_now, normal), axis=-1), np.sum(hinge_now * normal, axis=-1))
    upper_world = rot.multiply(rot.exp_map(thigh_dir * turn[..., None]), upper_world)
    shin_rest = offsets[..., LEG_INDEX[:, 2], :] + np.zeros_like(new_ankle)  # in the thigh's frame, unfolded
    shin_goal = rot.apply(rot.inverse(upper_world), new_ankle - new_knee)
    fold = np.arctan2(shin_goal[..., 2], shin_goal[..., 1]) - np.arctan2(shin_rest[..., 2], shin_rest[..., 1])
    lower_world = rot.multiply(upper_world, rot.exp_map(_KNEE_AXIS * fold[..., None]))
    out = np.empty((len(roots), 2, 3, 4))
    out[:, :, 0] = rot.multiply(rot.inverse(hips)[:, None], upper_world)  # the legs hang off the Hips
    out[:, :, 1] = rot.multiply(rot.inverse(upper_world), lower_world)
    out[:, :, 2] = rot.multiply(rot.inverse(lower_world), foot_world)
    return out


class FootLock:
    """Contact detection on the input stream and the lock on the output stream (see the
    module docstring). ``push`` every input frame (index t = 0, 1, ... in order), then
    ``apply`` output frames up to ``sight`` frames behind the newest pushed input."""

    def __init__(self, skeleton: Skeleton, ramp: int | None = None, settings: ContactSettings = ContactSettings(),
                 sight: int | None = None):
        if tuple(skeleton.names) != HUMANOID_BONES:
            raise ValueError("the foot lock works on the canonical humanoid skeleton")
        self.settings = settings
        self.ramp = settings.ramp if ramp is None else max(0, int(ramp))
        # Input frames beyond an output frame the lock may read (the stream's delay); the
        # ramp's frames further ahead it foresees (``approach``).
        self.sight = self.ramp if sight is None else min(max(0, int(sight)), self.ramp)
        self.release = self.ramp if settings.release is None else max(0, int(settings.release))
        # The contacts a frame's weight reads: ``back`` frames before it (the release's, at
        # least the ramp's, which the pelvis reads: ``_down``) and ``ramp`` after it.
        self.back = max(self.release, self.ramp)
        self._blend = lock_kernel(self.ramp, self.release, self.back)
        self.set_offsets(skeleton.offsets)
        self.pelvis = PelvisHeight(settings.pelvis_tau, settings.pelvis_cap, settings.pelvis_flight_tau,
                                   settings.flight_memory)
        self.stance = StanceOffset(settings)
        self.pace = Pace(settings)
        self.frames = 0  # input frames pushed
        self._planted = np.zeros(2, dtype=bool)  # hysteresis state per foot
        self._floor_history: deque = deque(maxlen=settings.floor_window)  # lower ball height per frame
        self._previous = None  # (2, 2, 3): the last pushed frame's ankles and balls, each foot's [x, y, z]
        # Per input frame from _base on: the contacts (left, right), the floor height seen
        # (-inf: none known yet) and both feet's ankle and ball, columns of one history.
        self._history = _History(_HISTORY_COLUMNS)
        self._base = 0
        self.planted_frames = 0  # counters (tests, benchmarks)
        self.locked_frames = 0

    @classmethod
    def for_stream(cls, skeleton: Skeleton, delay: int, settings: ContactSettings = ContactSettings(),
                   fade_in: int = 0, fade_tau: float = 0.0, lead_in: int = 0, aim: float = 1.0) -> "FootLock":
        """The lock a stream with ``delay`` frames of look-ahead can run: it reads at most
        ``delay`` input frames ahead (its ``sight``), and foresees the contacts of the
        ramp's frames beyond them (the daemon and ``restyle`` both build it here).
        ``fade_in``: the frames by which the stream's first fade from pass-through to the
        restyle has ended (``words.BlendSettings.first_fade_end``), its correction low-passed
        over ``fade_tau`` frames, towards the share ``aim`` (the intensity): the stance is
        taken at that share through it. ``lead_in``: frames before the shown ones (an offline
        clip's mirrored lead-in), over which the stance follows freely (see ``StanceOffset``)."""
        lock = cls(skeleton, settings=settings, sight=delay)
        lock.stance.for_fade(fade_in, fade_tau)
        lock.stance.free_until, lock.stance.aim = int(lead_in), float(aim)
        return lock

    def set_offsets(self, offsets: np.ndarray) -> None:
        """The performer's proportions changed (a calibration, a VMC sender's offsets)."""
        self.offsets = np.asarray(offsets, dtype=np.float64)
        self._leg_offsets = [[tuple(self.offsets[j]) for j in leg] for leg in LEGS]
        # How far the ankle sits above the ball when the foot stands flat: the foot bone's
        # vertical extent in the T-pose (feet point forward and down).
        self._ankle_rest = float(np.mean([-self.offsets[toes][1] for _, _, _, toes in LEGS]))
        # ...and what ``approach_columns`` reads of this lock: the kernel's weight just beyond
        # its sight (none where the sight covers the ramp: nothing is foreseen)
        s, beyond = self.settings, self.back + self.sight + 1
        self._approach_numbers = np.array([[self._ankle_rest, s.plant_height, s.plant_speed, s.release_height,
                                            self._blend[beyond] if beyond < len(self._blend) else 1.0]])

    # -- input side ---------------------------------------------------------------------
    def push(self, roots: np.ndarray, rotations: np.ndarray) -> np.ndarray:
        """Input frames (n, 3) roots and (n, J, 4) local rotations, in order. Returns
        their contacts (n, 2) bool (left, right)."""
        roots = np.asarray(roots, dtype=np.float64).reshape(-1, 3)
        rotations = np.asarray(rotations, dtype=np.float64).reshape(len(roots), -1, 4)
        ankle, ball = self._feet(roots, rotations)
        if len(roots) == 1:
            contacts, lowest = _contacts_of_locks([self], ankle, ball)
        else:
            contacts, lowest = self._contacts_of_frames(ankle, ball)
        return self._record(contacts, lowest, np.stack([ankle, ball], axis=1))

    @property
    def _contacts(self) -> np.ndarray:
        return self._history.rows[:, _CONTACTS] > 0

    @property
    def _floors(self) -> np.ndarray:
        return self._history.rows[:, _FLOOR]

    def _record(self, contacts: np.ndarray, lowest: np.ndarray, feet: np.ndarray) -> np.ndarray:
        """Input frames' contacts (n, 2), floor heights (n,) and feet (n, ankle/ball, foot,
        xyz) into the history (the output side reads the feet there rather than run the
        input's legs again)."""
        self._planted = contacts[-1].copy()
        # A floor is known once a foot has stood on it: before a stream's first contact the
        # lowest ball seen may be a foot in the air (a stream started mid-step or with
        # made-up motion: 35 cm up, falling 3.5 cm in a frame as lower steps came, and the
        # floor step's lift popped a knee by 12 degrees in one frame), so free feet are kept
        # above nothing (-inf) until then. (Only then: no work per frame once a foot has stood.)
        if not self.planted_frames:
            lowest = np.where(np.cumsum(contacts.any(axis=1)) > 0, lowest, -np.inf)
        self._history.extend(np.column_stack([contacts, lowest, feet.reshape(len(feet), -1)]))
        before, self.frames = self.frames, self.frames + len(contacts)
        self.planted_frames += int(contacts.sum())
        if before <= 1 < self.frames:
            self._first_frame_takes(contacts[1 - before])
        return contacts

    def _first_frame_takes(self, second: np.ndarray) -> None:
        """The stream's second frame is in, with its contacts ``second`` (2,): the first frame
        takes them. It had no speed of its own (nothing came before it: ``speed[0]``), so no
        contact, and a foot standing at the start of a stream shown restyled from its first
        frame (``words.BlendSettings.start_restyled``) slid with the restyle until its lock
        ramped in: held-out clips started live slid 2.3x the input's over their first 12
        frames, 1.15x with this (1.12x after those frames). (Its floor stays unknown.)"""
        if self._base == 0:
            self._history.rows[0, _CONTACTS] = second

    def _contacts_of_frames(self, ankle: np.ndarray, ball: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Contacts (n, 2) and floor heights (n,) of input frames, from their ankles and
        balls (n, 2, 3), the state carried on."""
        s = self.settings
        # Floor: the lowest ball height over the window, this frame included (causal).
        lowest = np.empty(len(ball))
        for i, h in enumerate(ball[:, :, 1].min(axis=1).tolist()):
            self._floor_history.append(h)
            lowest[i] = min(self._floor_history)
        # The ball rests at the floor, the ankle one foot-height above it.
        height = np.minimum(ball[:, :, 1] - lowest[:, None], ankle[:, :, 1] - lowest[:, None] - self._ankle_rest)
        prev = self._previous[:, None] if self._previous is not None else (ankle[:1], ball[:1])
        speed = np.minimum(_speeds(np.concatenate([prev[0], ankle])), _speeds(np.concatenate([prev[1], ball])))
        if self._previous is None:
            speed[0] = np.inf  # a stream's first frame has no speed yet: not planted
        self._previous = np.stack([ankle[-1], ball[-1]])
        plant, release = _plant_or_release(height, speed, s.plant_height, s.plant_speed, s.release_height,
                                           s.release_speed)
        return _hysteresis(plant, release, self._planted), lowest

    # -- output side --------------------------------------------------------------------
    def weights(self, t0: int, n: int) -> np.ndarray:
        """Lock weights (n, 2) of output frames t0 .. t0+n-1 (needs inputs to t0+n-1+sight)."""
        return self._weights_and_down(t0, n)[0]

    def _weights_and_down(self, t0: int, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The lock weights (n, 2) and which feet are down for the pelvis (n, 2)."""
        c = self._contact_window(t0, n, np.zeros((n + self.back + self.ramp, 2)))
        windows = sliding_window_view(c, self.back + self.ramp + 1, axis=0)  # (n, 2, kernel)
        if self.sight == self.ramp:
            return _lock_weights(windows, self._blend, self.back), _down(windows, self.ramp)
        windows = windows.copy()
        windows[..., self.back + self.sight + 1:] = 0.0  # beyond sight: not pushed yet, live
        down = _down(windows, self.ramp)
        newest = t0 + self.sight + np.arange(n)
        windows[..., self.back + self.sight + 1] = approach_columns(*self._approach_inputs(newest))
        return _lock_weights(windows, self._blend, self.back), down

    def _approach_inputs(self, newest: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What ``approach_columns`` reads for the output frames whose newest input frames are
        ``newest`` (n,): history rows (n, frames, columns), whether each frame has a step
        before it (n, frames - 1; none where the newest is not pushed) and the lock's numbers
        (n, 5). (The frames a lock forgets are older than its ``back``, which these never
        reach: only a stream's start lies before them.)"""
        i = np.asarray(newest) - self._base
        if len(i) == 1 and APPROACH_FRAMES <= i[0] < len(self._history):  # the daemon's tick: a slice
            return (self._history.rows[None, i[0] - APPROACH_FRAMES:i[0] + 1], _ALL_MOVED,
                    self._approach_numbers)
        frames = i[:, None] + np.arange(-APPROACH_FRAMES, 1)  # from the oldest
        rows = self._history.rows[np.clip(frames, 0, len(self._history) - 1)]
        moved = (frames[:, :-1] >= 0) & (i < len(self._history))[:, None]
        return rows, moved, np.repeat(self._approach_numbers, len(i), axis=0)

    def _contact_window(self, t0: int, n: int, out: np.ndarray) -> np.ndarray:
        """The contacts of frames t0 - back .. t0 + n - 1 + ramp written into ``out`` (n +
        back + ramp, 2, zeros), which is left as it is where none are known; a longer ``out``
        starts further back."""
        lo = t0 + n + self.ramp - len(out) - self._base
        a, b = max(lo, 0), min(lo + len(out), len(self._history))
        if a < b:
            out[a - lo:b - lo] = self._history.rows[a:b, _CONTACTS]
        return out

    def _pushed(self, t0: int, n: int) -> np.ndarray:
        """The history rows of input frames t0 .. t0+n-1 (IndexError where one is not kept)."""
        rows = self._history.rows[max(t0 - self._base, 0):t0 - self._base + n]
        if t0 < self._base or len(rows) != n:
            raise IndexError("output frames the lock has no input for")
        return rows

    def apply(self, t0: int, roots: np.ndarray, inputs: np.ndarray, outputs: np.ndarray,
              mix: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Output frames t0 .. t0+n-1, in order: their input roots (n, 3), input rotations
        and restyled rotations (n, J, 4), and the share of the restyle shown in each (n,)
        (the seam blender's mix, ``words.planned_mix``; None: all of it) -> the output's
        roots (the pelvis height and the pace set) and rotations (planted feet locked).
        The inputs are the frames ``push`` was given for t0 .. t0+n-1: their feet are read
        from what was pushed, not worked out again. ``plan`` then ``solve_lock_jobs`` for
        one lock."""
        job = self.plan(t0, roots, inputs, outputs, mix)
        solve_lock_jobs([job])
        return job.new_roots, job.result

    def plan(self, t0: int, roots: np.ndarray, inputs: np.ndarray, outputs: np.ndarray,
             mix: np.ndarray | None = None) -> "LockJob":
        """Output frames t0 .. t0+n-1 (as ``apply``'s) as a job for ``solve_lock_jobs``, which
        runs the jobs of many locks together; this part needs only the contacts pushed."""
        roots = np.asarray(roots, dtype=np.float64).reshape(-1, 3)
        w, down = self._weights_and_down(t0, len(roots))
        self._forget_before(t0 - self.back)
        pushed = self._pushed(t0, len(roots))
        return LockJob(self, t0, roots, np.asarray(inputs, dtype=np.float64), np.asarray(outputs, dtype=np.float64),
                       w, down, pushed[:, _FLOOR], mix, own=pushed[:, _FEET].reshape(len(roots), 2, 2, 3))

    def _feet(self, roots: np.ndarray, rotations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ankle and ball positions (n, 2, 3) of both legs."""
        if len(roots) == 1:  # the daemon's case, one frame per tick: plain floats
            ankle, ball = _feet_of_one_frame(roots[0], rotations[0], self._leg_offsets)
            return np.array([ankle]), np.array([ball])
        pos, _, _ = leg_chain(roots, rotations, self.offsets)
        return pos[:, :, 2], pos[:, :, 3]

    def _forget_before(self, t: int) -> None:
        drop = t - self._base
        if drop > 256:  # trim in chunks: a long stream keeps a bounded history
            self._history.drop(drop)
            self._base += drop


def push_frames(rows: list) -> None:
    """``FootLock.push`` of one input frame per row, (lock, root (3,), rotations (J, 4)),
    for many locks at once (a lock's rows in its frames' order): the daemon's tick. The
    legs' forward kinematics of every row in one vectorised ``leg_chain``, each row with
    its lock's proportions (one frame's on Python floats was 18 of a push's 30 us, per
    performer and frame), then the contacts of every lock's next frame in one pass
    (``_contacts_of_locks``; a lock with several frames this tick takes several passes)."""
    if not rows:
        return
    pos, _, _ = leg_chain(np.array([root for _, root, _ in rows], dtype=np.float64),
                          np.array([rotations for _, _, rotations in rows], dtype=np.float64),
                          np.array([lock.offsets for lock, _, _ in rows]))
    passes: list[list[int]] = []  # rows by pass: each lock's n-th frame of the tick in pass n
    frames_of: dict[int, int] = {}
    for i, (lock, _, _) in enumerate(rows):
        n = frames_of.get(id(lock), 0)
        frames_of[id(lock)] = n + 1
        if n == len(passes):
            passes.append([])
        passes[n].append(i)
    for at in passes:
        locks = [rows[i][0] for i in at]
        contacts, lowest = _contacts_of_locks(locks, pos[at, :, 2], pos[at, :, 3])
        # Each lock's record (``_record``) of its one frame: the floor unknown (-inf) until
        # a foot of the stream has stood. Written out for all locks rather than a ``_record``
        # call each: 20-30 % of push_frames at 64 locks, six of seven alternated rounds.
        known = contacts.any(axis=1) | np.array([lock.planted_frames > 0 for lock in locks])
        feet = np.stack([pos[at, :, 2], pos[at, :, 3]], axis=1).reshape(len(at), -1)
        records = np.column_stack([contacts, np.where(known, lowest, -np.inf), feet])
        for lock, row, planted, count in zip(locks, records, contacts, contacts.sum(axis=1).tolist()):
            lock._planted = planted
            lock._history.append(row)
            lock.frames += 1
            lock.planted_frames += count
            if lock.frames == 2:
                lock._first_frame_takes(planted)


_ALL_MOVED = np.ones((1, APPROACH_FRAMES), dtype=bool)  # ``FootLock._approach_inputs``' common case

# The columns of a lock's per-frame history (``FootLock._history``).
_CONTACTS, _FLOOR, _FEET = slice(0, 2), 2, slice(3, 15)  # _FEET: (ankle, ball) x (left, right) x xyz
_HISTORY_COLUMNS = 15


class _History:
    """Rows of numbers appended at the end and dropped from the front, in one preallocated
    array: appending a frame by concatenation copied the whole history every frame, per
    performer."""

    def __init__(self, columns: int, capacity: int = 512):
        self._rows = np.zeros((capacity, columns))
        self._count = 0

    def __len__(self) -> int:
        return self._count

    @property
    def rows(self) -> np.ndarray:
        return self._rows[:self._count]

    def _room(self, n: int) -> None:
        if self._count + n > len(self._rows):
            grown = np.zeros((max(2 * len(self._rows), self._count + n), self._rows.shape[1]))
            grown[:self._count] = self.rows
            self._rows = grown

    def append(self, row: np.ndarray) -> None:
        self._room(1)
        self._rows[self._count] = row
        self._count += 1

    def extend(self, rows: np.ndarray) -> None:
        self._room(len(rows))
        self._rows[self._count:self._count + len(rows)] = rows
        self._count += len(rows)

    def drop(self, n: int) -> None:
        """Forget the first ``n`` rows."""
        kept = self._rows[n:self._count].copy()
        self._rows[:len(kept)] = kept
        self._count = len(kept)


def _contacts_of_locks(locks: list[FootLock], ankles: np.ndarray, balls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One input frame of each of many locks (each lock once), its ankles and balls (P, 2,
    3) -> contacts (P, 2) and floor heights (P,), each lock's state carried on as
    ``_contacts_of_frames`` carries it for one lock's frames (the same arithmetic: the
    stream-vs-clip test holds them equal). One pass for all: per lock and frame, numpy's
    per-call cost was most of the contact test's cost."""
    feet = np.stack([ankles, balls], axis=1)  # (P, ankle/ball, foot, xyz)
    previous = feet.copy()
    started = np.ones(len(locks), dtype=bool)
    planted = np.empty((len(locks), 2), dtype=bool)
    lowest = np.empty(len(locks))
    rest = np.empty(len(locks))
    thresholds = np.empty((len(locks), 4))
    for k, (lock, ball) in enumerate(zip(locks, balls[:, :, 1].min(axis=1).tolist())):
        # Floor: the lowest ball height over the lock's window, this frame included (causal).
        lock._floor_history.append(ball)
        lowest[k] = min(lock._floor_history)
        if lock._previous is None:
            started[k] = False
        else:
            previous[k] = lock._previous
        lock._previous = feet[k]
        planted[k] = lock._planted
        rest[k] = lock._ankle_rest
        s = lock.settings
        thresholds[k] = (s.plant_height, s.plant_speed, s.release_height, s.release_speed)
    # The ball rests at the floor, the ankle one foot-height above it.
    height = np.minimum(balls[:, :, 1] - lowest[:, None], ankles[:, :, 1] - lowest[:, None] - rest[:, None])
    speed = np.linalg.norm(feet - previous, axis=-1).min(axis=1)
    speed[~started] = np.inf  # a stream's first frame has no speed yet: not planted
    plant, release = _plant_or_release(height, speed, *thresholds.T[:, :, None])
    return np.where(plant, True, np.where(release, False, planted)), lowest


def lock_kernel(ramp: int, release: int, back: int) -> np.ndarray:
    """The lock weight a contact gives the frames around it, over ``back`` frames before one
    (zero beyond ``release``) and ``ramp`` after it, from past to future: a smoothstep of a
    triangle each side, so the lock sets in and lets go with zero slope. A linear ramp's
    corners at touch-down were the largest jerk of a restyled walk (its largest one-frame
    jerk 1.33x the input's, median over held-out walks; 1.01x smoothstepped; runs 1.88x ->
    1.51x, planted-foot slide 1.32 -> 1.16)."""
    linear = np.zeros(back + ramp + 1)
    linear[back - release:back] = 1.0 - np.arange(release, 0, -1) / (release + 1)  # a contact that has ended
    linear[back:] = 1.0 - np.arange(ramp + 1) / (ramp + 1)  # a contact to come
    return linear * linear * (3.0 - 2.0 * linear)


def _lock_weights(windows: np.ndarray, kernel: np.ndarray, back: int) -> np.ndarray:
    """Contact windows (..., back + ramp + 1) and their kernel (``lock_kernel``) -> the lock
    weights: the nearest contact before a frame lets go, the nearest one from it on sets in,
    and the two are joined as 1 - (1 - letting go)(1 - setting in), which is smooth where
    the two overlap (a swing shorter than release + ramp frames). Their larger one has a
    corner there: a foot set down 7 frames into a clip, its lock over the mirrored lead-in
    let go over 8 frames, popped the toes at 6.7 cm/frame^3 (the input's largest: 2.4)."""
    before = (windows[..., :back] * kernel[..., :back]).max(axis=-1, initial=0.0)
    after = (windows[..., back:] * kernel[..., back:]).max(axis=-1)
    return 1.0 - (1.0 - before) * (1.0 - after)


def approach_columns(rows: np.ndarray, moved: np.ndarray, numbers: np.ndarray) -> np.ndarray:
    """``FootLock._approach_inputs`` of one or many locks (m rows) -> the contact windows'
    value (m, 2) for the frame just beyond each lock's sight: ``approach`` as the weight the
    lock kernel there gives it."""
    ankle_rest, plant_height, plant_speed, release_height = (n[:, None, None] for n in numbers[:, :4].T)
    near = approach(rows, moved, ankle_rest, plant_height, plant_speed, release_height)
    column = numbers[:, 4:]
    return np.minimum(near, column) / column


def approach(rows: np.ndarray, moved: np.ndarray, ankle_rest, plant_height, plant_speed,
             release_height) -> np.ndarray:
    """A lock's history rows of APPROACH_FRAMES + 1 consecutive input frames (m, frames,
    columns) -> how far each foot of the last has come down to a contact (m, 2), in [0, 1]:
    per frame, 1 where the foot is as low and slow as the contact test plants it, 0 from
    ``release_height`` up or ``APPROACH_SPEED`` on, smoothstepped between, and 0 where no
    floor is known yet; then slew-limited to ``APPROACH_SLEW`` a frame over the frames read,
    from a stream's first step on (``moved`` (m, frames - 1): the frame has a step before
    it; nothing was shown before a stream started, so a foot coming down in its first
    frames is not held back).

    Why: a lock sets in over ``ramp`` frames before a contact, and a stream with less delay
    than that (``--latency low``: one frame) saw the contact too late and snapped the lock
    in over a frame. A foot coming down slows on its way, so the lock sets in as it does
    (``FootLock.sight``). Measured on the training split's normal clips with the pair
    default at hop 1 (a scratch screen; the held-out figures are in the model card): jerk
    1.19x the input's -> 1.08x, planted-foot slide 1.59x -> 1.10x, the worst clip's largest
    one-frame jerk 3.6x -> 2.6x (the real contacts four frames ahead: 1.03x, 1.10x, 2.1x).
    Unlimited, a walk's speed, stepped as a 30 Hz capture's is, switched the lock in by 0.65
    in one frame (6.0x the input's largest one-frame jerk); limited from the frames after a
    floor became known alone, a live walk's first frames popped a foot at 7.3x; and a foot
    lifting slowly off the floor let go at once. A wrong guess costs little: the lock's
    target is the input's own foot."""
    feet = rows[:, :, _FEET].reshape(*rows.shape[:2], 2, 2, 3)  # (m, frame, ankle/ball, foot, xyz)
    floor = rows[:, 1:, _FLOOR][..., None]
    height = np.minimum(feet[:, 1:, 1, :, 1] - floor, feet[:, 1:, 0, :, 1] - floor - ankle_rest)  # (m, frame, foot)
    speed = np.linalg.norm(np.diff(feet, axis=1), axis=-1).min(axis=2)  # (m, frame, foot)
    slow = np.clip((APPROACH_SPEED - speed) / (APPROACH_SPEED - plant_speed), 0.0, 1.0)
    low = np.clip((release_height - height) / (release_height - plant_height), 0.0, 1.0)
    near = np.where(moved[..., None], _smoothstep(slow) * _smoothstep(low), np.nan)  # (m, frame, foot)
    # Slew-limited over the frames read, from the first with a step (NaN: none yet)
    slewed = near[:, 0]
    for frame in near.transpose(1, 0, 2)[1:]:
        slewed = np.where(np.isnan(slewed), frame,
                          np.clip(frame, slewed - APPROACH_SLEW, slewed + APPROACH_SLEW))
    return np.nan_to_num(slewed, nan=0.0)


def _smoothstep(x: np.ndarray) -> np.ndarray:
    return x * x * (3.0 - 2.0 * x)


def _down(windows: np.ndarray, ramp: int) -> np.ndarray:
    """Contact windows (..., back + ramp + 1) -> whether a contact lies within ``ramp``
    frames either side: the feet the pelvis stands on (``PelvisHeight``). A foot that a
    longer release still holds is lifting, and its gap is no stance: counted, it dropped the
    hips and popped a knee (the pair default's worst held-out clip: 1.2 -> 2.6x the input's
    largest one-frame jerk with an 8-frame release)."""
    return windows[..., windows.shape[-1] - 2 * ramp - 1:].max(axis=-1) > 0


def _plant_or_release(height, speed, plant_height, plant_speed, release_height, release_speed):
    """The contact test's events per frame and foot: a foot low and still plants, one high
    or fast lets go (``ContactSettings``; thresholds scalars or one per row)."""
    return (height < plant_height) & (speed < plant_speed), (height > release_height) | (speed > release_speed)


def plan_locks(items: list) -> list["LockJob"]:
    """``FootLock.plan`` of one output frame for each of many locks, (lock, t, input root
    (3,), input rotations (J, 4), restyled rotations (J, 4), mix (1,) or None), the daemon's
    tick: the lock weights of all in one pass (per lock, the window's few numpy calls were
    most of ``plan``). Locks of different ramps plan one by one; different releases (the
    ``input`` and ``stance`` locks) share the pass, each with its own kernel."""
    if len({lock.ramp for lock, *_ in items}) > 1:
        return [lock.plan(t, root, inputs[None], outputs[None], mix) for lock, t, root, inputs, outputs, mix in items]
    ramp = items[0][0].ramp if items else 0
    back = max((lock.back for lock, *_ in items), default=ramp)
    windows = np.zeros((len(items), back + ramp + 1, 2))  # contacts t - back .. t + ramp, zero where not known
    kernels = np.zeros((len(items), back + ramp + 1))
    pushed = np.empty((len(items), _HISTORY_COLUMNS))
    short = []  # (row, column beyond sight, approach inputs) of the locks that see less than their ramp
    for k, (lock, t, *_) in enumerate(items):
        lock._contact_window(t, 1, windows[k])
        if lock.sight < ramp:
            windows[k, back + lock.sight + 1:] = 0.0  # beyond sight: not pushed yet, live
            short.append((k, back + lock.sight + 1, lock._approach_inputs(np.array([t + lock.sight]))))
        kernels[k, back - lock.back:] = lock._blend
        pushed[k] = lock._pushed(t, 1)[0]
        lock._forget_before(t - lock.back)
    windows = windows.transpose(0, 2, 1)  # (locks, 2, kernel)
    down = _down(windows, ramp)
    if short:
        near = approach_columns(*(np.concatenate(part) for part in zip(*(inputs for _, _, inputs in short))))
        windows[[k for k, _, _ in short], :, [column for _, column, _ in short]] = near
    weights = _lock_weights(windows, kernels[:, None], back)
    own = pushed[:, _FEET].reshape(len(items), 2, 2, 3)
    return [LockJob(lock, t, np.asarray(root, dtype=np.float64).reshape(1, 3),
                    np.asarray(inputs, dtype=np.float64)[None], np.asarray(outputs, dtype=np.float64)[None],
                    weights[k:k + 1], down[k:k + 1], pushed[k:k + 1, _FLOOR], mix, own=own[k:k + 1])
            for k, (lock, t, root, inputs, outputs, mix) in enumerate(items)]


@dataclass(eq=False)
class LockJob:
    """One lock's output frames t0 .. t0+n-1 from ``FootLock.plan`` to ``solve_lock_jobs``:
    input ``roots`` (n, 3), input and restyled rotations (n, J, 4), lock ``weights`` (n, 2),
    which feet are ``down`` for the pelvis (n, 2), the ``floor`` (n,), the restyle's ``mix``
    (n,) or None, and the input's feet ``own`` (n, ankle/ball, foot, xyz) as pushed. Solving
    fills in ``new_roots`` (the pelvis height and the pace set) and ``result``, the locked
    rotations."""

    lock: FootLock
    t0: int
    roots: np.ndarray
    inputs: np.ndarray
    outputs: np.ndarray
    weights: np.ndarray
    down: np.ndarray
    floor: np.ndarray
    mix: np.ndarray | None = None
    own: np.ndarray | None = None
    new_roots: np.ndarray | None = None
    result: np.ndarray | None = None


def solve_lock_jobs(jobs: list[LockJob]) -> None:
    """Many locks' jobs (the daemon: every performer's frame of this tick) in one vectorised
    pass, each frame with its own performer's proportions: the pelvis height and stance
    (each lock's state advanced in order), the lock of planted feet, then the floor (see
    the module docstring). Run per lock, numpy's per-call cost was 55x the work
    (``bench_daemon.py footlock``). Each job is solved once, in the order of its frames."""
    if not jobs:
        return
    rows = _Rows(jobs)
    _advance(rows)
    _carry_free_feet(rows)
    for with_stance in (False, True):  # the two kinds of target: one pass each
        _lock_planted(rows, np.flatnonzero((rows.weights.max(axis=1) > 0) & (rows.with_stance == with_stance)))
    _keep_above_floor(rows)
    for job, (lo, hi) in zip(jobs, rows.spans):
        job.new_roots, job.result = rows.new_roots[lo:hi], rows.result[lo:hi]


class _Rows:
    """Every job's frames stacked into one set of rows, the arrays the vectorised passes
    work on (``result`` is written in place), with each row's performer's proportions."""

    def __init__(self, jobs: list[LockJob]):
        self.jobs = jobs
        sizes = [len(j.roots) for j in jobs]
        ends = np.cumsum(sizes)
        self.spans = list(zip((ends - sizes).tolist(), ends.tolist()))
        stack = (lambda f: f(jobs[0])) if len(jobs) == 1 else (lambda f: np.concatenate([f(j) for j in jobs]))
        self.roots, self.inputs, self.outputs = stack(lambda j: j.roots), stack(lambda j: j.inputs), \
            stack(lambda j: j.outputs)
        self.weights, self.floor, self.own_feet = stack(lambda j: j.weights), stack(lambda j: j.floor), \
            stack(lambda j: j.own)
        self.down = stack(lambda j: j.down)
        # (J, 3) for one lock, (rows, J, 3) for several (leg_chain takes either)
        self.offsets = jobs[0].lock.offsets if len(jobs) == 1 else \
            np.repeat(np.stack([j.lock.offsets for j in jobs]), sizes, axis=0)
        self.ankle_rest = np.repeat([j.lock._ankle_rest for j in jobs], sizes)
        self.with_stance = np.repeat([j.lock.stance.cap > 0 for j in jobs], sizes)
        self.result = self.outputs.copy()  # the caller's outputs stay as they are
        self.new_roots = self.own = self.stance = None  # set by ``_advance``
        self.feet_shift = np.zeros((len(self.roots), 2, 2))  # ``Pace``: each foot's (x, z) ...
        self.carry = np.zeros((len(self.roots), 2, 2))  # ...and how far it lags the body's

    def offsets_of(self, rows: np.ndarray) -> np.ndarray:
        return self.offsets if self.offsets.ndim == 2 else self.offsets[rows]


def _advance(rows: _Rows) -> None:
    """Where the restyled feet stand against the input's (the input's as they were pushed,
    the restyle's legs in one forward kinematics call for every row): the ankles' height
    gap sets the pelvis, the rest the stance (``--feet stance``); each lock's state moves
    on, in order."""
    jobs = rows.jobs
    own = (rows.own_feet[:, 0], rows.own_feet[:, 1])
    if len(jobs) == 1:  # one lock (one performer, or a clip): its own path, floats for one frame
        restyled = jobs[0].lock._feet(rows.roots, rows.outputs)
    else:
        pos_out, _, _ = leg_chain(rows.roots, rows.outputs, rows.offsets)
        restyled = (pos_out[:, :, 2], pos_out[:, :, 3])
    rows.own = own  # the input's ankles and balls: the lock's targets and the floor's ceiling
    gap = restyled[0][..., 1] - own[0][..., 1]  # (rows, 2)
    rows.new_roots = rows.roots.copy()
    rows.stance = np.zeros((len(rows.roots), 2, 3))
    planted, down = rows.weights > 0, rows.down
    if len(jobs) > 1 and len(rows.roots) == len(jobs):
        _advance_one_frame_each(rows, restyled, gap, planted)
        return
    for job, (lo, hi) in zip(jobs, rows.spans):
        lock = job.lock
        rows.new_roots[lo:hi, 1] -= lock.pelvis.drops(np.where(down[lo:hi], gap[lo:hi], 0.0), down[lo:hi])
        stance = lock.stance.track(job.t0, (own[0][lo:hi], own[1][lo:hi]),
                                   (restyled[0][lo:hi], restyled[1][lo:hi]), planted[lo:hi], job.mix)
        if stance is not None:
            rows.stance[lo:hi] = stance
        pace = lock.pace.track(job.roots, job.weights, job.mix)
        if pace is not None:
            body, feet = pace
            rows.new_roots[lo:hi, 0] -= body[:, 0]
            rows.new_roots[lo:hi, 2] -= body[:, 1]
            rows.feet_shift[lo:hi] = feet
            rows.carry[lo:hi] = body[:, None] - feet
        lock.locked_frames += int(np.count_nonzero(job.weights >= 1.0))


def _advance_one_frame_each(rows: _Rows, restyled: tuple, gap: np.ndarray, planted: np.ndarray) -> None:
    """``_advance`` where every lock has one frame (the daemon's tick): the stances'
    targets in one pass for all (``stance_targets``, each row with its lock's settings),
    then each lock's recurrences step on Python floats read out of the rows in one go, and
    their results go back into the rows in one go. Why: per lock, numpy's slicing and small
    arrays cost more than the recurrences' own arithmetic (a sampling profile of 64
    performers: that loop was 11 % of the process's time). ``solve_lock_jobs`` for 64
    locks, one frame each (min of 7 rounds, interleaved with the per-lock loop in one
    process): 4.8 -> 3.6 ms a tick with ``--feet input``, 8.9 -> 4.3 ms with the stance,
    the results bit for bit the same."""
    jobs = rows.jobs
    gaps, down, held = np.where(rows.down, gap, 0.0).tolist(), rows.down.tolist(), planted.tolist()
    xz, weights = rows.roots[:, [0, 2]].tolist(), rows.weights.tolist()
    shown = [1.0 if job.mix is None else float(job.mix[0]) for job in jobs]
    at = [i for i, job in enumerate(jobs) if job.lock.stance.cap > 0]  # the rows with a stance (--feet stance)
    if at:
        stances = [jobs[i].lock.stance for i in at]
        per_row = np.array([[s.cap, s.turn_cap, s.turn_unsure, s.turn_sure] for s in stances])
        wanted, sure = stance_targets((rows.own[0][at], rows.own[1][at]), (restyled[0][at], restyled[1][at]),
                                      per_row[:, 0, None, None], per_row[:, 1, None, None], per_row[:, 2, None],
                                      per_row[:, 3, None])
        wanted, sure = wanted.tolist(), sure.tolist()
        rows.stance[at] = [stance.follow(jobs[i].t0, [wanted[k]], [held[i]], [sure[k]], [shown[i]])[0]
                           for k, (i, stance) in enumerate(zip(at, stances))]
    drops, paced, body, feet = [], [], [], []
    for i, job in enumerate(jobs):
        lock = job.lock
        drops.append(lock.pelvis.drop_of_one_frame(gaps[i], down[i]))
        shift = lock.pace.track_one_frame(*xz[i], *weights[i], shown[i])
        if shift is not None:
            paced.append(i)
            body.append(shift[0])
            feet.append(shift[1])
        lock.locked_frames += (weights[i][0] >= 1.0) + (weights[i][1] >= 1.0)
    rows.new_roots[:, 1] -= drops
    if paced:
        body, feet = np.array(body), np.array(feet)
        rows.new_roots[paced, 0] -= body[:, 0]
        rows.new_roots[paced, 2] -= body[:, 1]
        rows.feet_shift[paced] = feet
        rows.carry[paced] = body[:, None] - feet


def _carry_free_feet(rows: _Rows) -> None:
    """``Pace``: a foot not fully locked goes where its (restyled) leg puts it, moved by how
    far its own shift lags the body's (the leg IK, the foot keeping its world rotation), in
    by the carry needed over CARRY_EASE, as the floor step eases its lift."""
    size = np.linalg.norm(rows.carry, axis=-1)  # (rows, 2)
    need = (rows.weights < 1.0) & (size > 0.0)
    at = np.flatnonzero(need.any(axis=1))
    if not len(at):
        return
    roots, outputs, offsets = rows.new_roots[at], rows.result[at], rows.offsets_of(at)
    chain = leg_chain(roots, outputs, offsets)
    pos, world, _ = chain
    target = pos[:, :, 2].copy()
    target[..., [0, 2]] += rows.carry[at]
    solved = solve_legs(roots, outputs, offsets, target, world[:, :, 2], chain)
    legs = LEG_INDEX[:, :3]
    eased = np.where(need[at], np.clip(size[at] / CARRY_EASE, 0.0, 1.0), 0.0)
    weight = np.broadcast_to(eased[:, :, None], solved.shape[:-1])
    rows.result[at[:, None, None], legs[None]] = rot.slerp(outputs[:, legs], solved, weight)


def _lock_planted(rows: _Rows, at: np.ndarray) -> None:
    """Rows ``at``, where a lock weight is above 0: the leg IK onto the input's ankle (or
    beside it, with the stance; less the foot's ``Pace`` shift), the foot turned as the
    input's, the knee in its restyled plane, slerped with the restyled (and carried) leg by
    the weight."""
    if not len(at):
        return
    offsets, inputs, outputs = rows.offsets_of(at), rows.inputs[at], rows.result[at]
    pos_in, world_in, _ = leg_chain(rows.roots[at], inputs, offsets)
    ankle, foot = pos_in[:, :, 2].copy(), world_in[:, :, 2]  # the input's own
    ankle[..., [0, 2]] -= rows.feet_shift[at]
    if rows.with_stance[at[0]]:  # beside them, turned as restyled
        stance = rows.stance[at]
        ankle = ankle + stance[:, :, :2] @ np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        foot = rot.multiply(rot.exp_map(stance[:, :, 2:] * np.array([0.0, 1.0, 0.0])), foot)
    solved = solve_legs(rows.new_roots[at], outputs, offsets, ankle, foot)
    target = np.concatenate([solved, inputs[:, LEG_INDEX[:, 3:]]], axis=2)  # toes as the input's
    weight = np.broadcast_to(rows.weights[at][:, :, None], target.shape[:-1])
    rows.result[at[:, None, None], LEG_INDEX[None]] = rot.slerp(outputs[:, LEG_INDEX], target, weight)


def _keep_above_floor(rows: _Rows) -> None:
    """A foot in the air can go through the floor the input's foot cleared: a restyled
    leg straighter than the input's, a foot pitched further down, or (most, measured
    2.7 cm at the 99th percentile on held-out clips without this step) the lowered
    pelvis. Where the ankle would go below its standing height over the floor, or the
    ball below the floor, the leg IK lifts the ankle (the foot keeps its rotation, the
    knee its plane) until both clear it (a lift under FLOOR_LIFT_EASE only in part: up to
    1.25 mm short), through a soft edge (``_soft_floor``), never
    higher than the input's own foot there (``own``: its ankles and balls). Near the
    floor the input's own clearance counts too (``kept_clearance``): a heel the input
    holds 2 cm up as it lands is not put down on the floor early and dragged there.
    Lifting the ankle rather than pitching the foot up: a foot pointing down needs a large turn for a
    small lift (measured: an 8-degree pop in one frame). A fully locked foot (weight 1) is
    the input's own, above the floor by definition, and is skipped: most frames of a
    stream."""
    free = rows.weights < 1.0
    at = np.flatnonzero(free.any(axis=1))
    if not len(at):
        return
    everywhere = leg_chain(rows.new_roots[at], rows.result[at], rows.offsets_of(at))
    pos = everywhere[0]
    floor, rest = rows.floor[at, None], rows.ankle_rest[at, None]
    own_ankle, own_ball = rows.own[0][at, :, 1], rows.own[1][at, :, 1]
    ankle_floor = np.maximum(np.minimum(floor + rest, own_ankle), kept_clearance(own_ankle, floor + rest))
    ball_floor = np.maximum(np.minimum(floor, own_ball), kept_clearance(own_ball, floor))
    near = free[at] & ((pos[:, :, 2, 1] < ankle_floor + FLOOR_MARGIN) | (pos[:, :, 3, 1] < ball_floor + FLOOR_MARGIN))
    keep = near.any(axis=1)
    at, near, ankle_floor, ball_floor = at[keep], near[keep], ankle_floor[keep], ball_floor[keep]
    own_ankle, own_ball = own_ankle[keep], own_ball[keep]
    if not len(at):
        return
    roots, outputs, offsets = rows.new_roots[at], rows.result[at], rows.offsets_of(at)
    chain = tuple(x[keep] for x in everywhere)
    pos, world, _ = chain
    up = np.maximum(
        _soft_floor(pos[:, :, 2, 1], ankle_floor, own_ankle) - pos[:, :, 2, 1],
        _soft_floor(pos[:, :, 3, 1], ball_floor, own_ball) - pos[:, :, 3, 1])
    lift = near & (up > 0)
    if not lift.any():
        return
    target = pos[:, :, 2].copy()
    target[..., 1] += up
    solved = solve_legs(roots, outputs, offsets, target, world[:, :, 2], chain)
    legs = LEG_INDEX[:, :3]
    # In by the lift needed, not at once: the solve moves a nearly straight knee even for
    # a lift of nothing (the hinge, the soft reach), and a leg switched in and out jumped.
    eased = np.where(lift, np.clip(up / FLOOR_LIFT_EASE, 0.0, 1.0), 0.0)
    weight = np.broadcast_to(eased[:, :, None], solved.shape[:-1])
    rows.result[at[:, None, None], legs[None]] = rot.slerp(outputs[:, legs], solved, weight)


def kept_clearance(own: np.ndarray, base: np.ndarray) -> np.ndarray:
    """The height a foot joint in the air may not go below for the input's own height
    ``own`` over ``base`` (its height standing on the floor): the input's clearance
    ``own - base``, saturating smoothly at CLEARANCE_BAND (band * tanh(clearance / band)),
    less CLEARANCE_SLACK. Smoothly: capped with a corner (min(clearance, band)), the floor
    stopped dead as a lifting foot passed the band, and a held-out walk's shuffling step
    popped a knee (1.64x the input's largest jerk)."""
    clearance = np.maximum(own - base, 0.0)
    return base + CLEARANCE_BAND * np.tanh(clearance / CLEARANCE_BAND) - CLEARANCE_SLACK


def _soft_floor(height: np.ndarray, floor: np.ndarray, own: np.ndarray) -> np.ndarray:
    """A floor with a soft edge: heights FLOOR_MARGIN or more above ``floor`` unchanged,
    anything below the floor put on it, and in between a quadratic that meets both with
    the same slope; never raised above ``own``, the input's own height there (so a foot
    the lock put where the input's is stays there). A hard clamp's corner in the foot's
    path showed as jerk (all joints 1.096x the input's, feet 1.27x; 1.087x and 1.24x with
    the edge)."""
    u = np.clip((height - floor) / FLOOR_MARGIN, -1.0, 1.0)
    eased = np.where(height - floor >= FLOOR_MARGIN, height, floor + FLOOR_MARGIN * (u + 1.0) ** 2 / 4.0)
    return np.where(height >= own, height, np.minimum(eased, own))


def _qmul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def _qrot(q, v):
    x, y, z, w = q
    vx, vy, vz = v
    cx, cy, cz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx  # u x v
    dx, dy, dz = y * cz - z * cy, z * cx - x * cz, x * cy - y * cx  # u x (u x v)
    return vx + 2 * (w * cx + dx), vy + 2 * (w * cy + dy), vz + 2 * (w * cz + dz)


def _feet_of_one_frame(root, rotations, leg_offsets):
    """``leg_chain`` for one frame, on Python floats: ankle and ball positions of both
    legs. Written out because the daemon pushes one frame per tick per performer, where
    numpy's per-call cost was most of the foot lock's (measured 0.3 of 0.5 ms a frame);
    tests/test_footlock.py checks it against the numpy path."""
    hips = tuple(rotations[HIPS].tolist())
    root = tuple(root.tolist())
    ankles, balls = [], []
    for leg, offsets in zip(LEGS, leg_offsets):
        rot_, pos = hips, root
        joints = []
        for j, off in zip(leg, offsets):
            d = _qrot(rot_, off)
            pos = (pos[0] + d[0], pos[1] + d[1], pos[2] + d[2])
            rot_ = _qmul(rot_, tuple(rotations[j].tolist()))
            joints.append(pos)
        ankles.append(joints[2])
        balls.append(joints[3])
    return ankles, balls


def _heading(v: np.ndarray) -> np.ndarray:
    """(..., 3) -> the angle about the vertical (radians) that turns +Z onto v's floor part."""
    return np.arctan2(v[..., 0], v[..., 2])


def _floor_length(v: np.ndarray) -> np.ndarray:
    """(..., 3) -> the length of v's floor part (the vertical is y)."""
    return np.hypot(v[..., 0], v[..., 2])


def _speeds(positions: np.ndarray) -> np.ndarray:
    """(n+1, 2, 3) consecutive positions -> (n, 2) distance moved per frame."""
    return np.linalg.norm(np.diff(positions, axis=0), axis=-1)


def _hysteresis(plant: np.ndarray, release: np.ndarray, start: np.ndarray) -> np.ndarray:
    """State per frame and foot: on at ``plant``, off at ``release``, else as before,
    vectorised: each frame takes the most recent event at or before it."""
    n = len(plant)
    event = np.where(plant, 1, np.where(release, -1, 0))  # the two tests never hold together
    idx = np.where(event != 0, np.arange(n)[:, None], -1)
    last = np.maximum.accumulate(idx, axis=0)
    taken = np.take_along_axis(event, np.maximum(last, 0), axis=0)
    return np.where(last >= 0, taken > 0, start[None, :])
