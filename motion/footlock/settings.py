"""What the foot lock does, per ``--feet`` and ``--pace``: ``ContactSettings``, the named locks
(``FEET``) and the checks of the two options' names."""

from __future__ import annotations

from dataclasses import dataclass, replace

from ..errors import UserError


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
    # ...and the quicker time constant a style may ask for while a foot is down, in the
    # share of the low-pass its mix sets (the restyler's ``quick_hips``; 0: pelvis_tau's
    # alone). The stance keeps 8 frames, but masculine reads more as itself at 2, active
    # with half of it (``FEET``).
    pelvis_quick_tau: float = 2.0
    pelvis_quick_share: float = 0.0
    # ...and the time constant once the body has left the floor (no foot locked: 11-24 % of
    # a held-out run's frames, none of any other action's) within the last flight_memory
    # frames (0.5 s, a run's stride and more). A run plants each foot for a few frames
    # between flights, and hips that drop by each new contact's gap within 2 frames snapped
    # the knee (a model trained with --lambda-action 0.25: 2.52x the input's largest jerk
    # with 2, 1.19x with 8, on the same held-out run).
    pelvis_flight_tau: float = 8.0
    flight_memory: int = 30
    # Stance: the most a planted foot stands beside the input's (cm; 0: on the input's
    # own ankle) and how fast the offset may move while the foot is locked (cm/frame;
    # 0: not at all, the foot stays where it landed beside the input's until it lifts).
    # None, because the restyled stance wanders while a performer stands still (the
    # multistyle model's held-out raises and waves towards active: 1-1.5 cm and 3-5
    # degrees standard deviation over a take): following it at 0.01 cm and 0.04 degrees a
    # frame, the previous setting, moved standing feet 0.011-0.013 cm a frame against the
    # input's 0.005 (2.2-2.8x in the standing actions of every stance style); a dead band
    # of 4 cm and 10 degrees before following still left 1.4-1.8x; none leaves 1.00.
    stance_cap: float = 0.0
    stance_rate: float = 0.0
    # ...and whether a new contact's offset settles through the lock's blend-in: it moves by
    # the share of the lock not yet set (1 - weight), so it eases to a stop at touch-down,
    # and holds from there (False: frozen where the lock starts to blend in, ``ramp``
    # frames before touch-down). Frozen there it was the swinging foot's: the multistyle
    # model's feminine walks froze a foot 7.9 cm inward where the restyled foot stood
    # 1.5-2.5 cm inward through the contact, the ankles 3.1-4.2 cm apart and crossed in
    # 3-9 % of frames (three held-out walks); settled 4.3-5.4 cm, crossed in 0-1.3 %, the
    # slide 1.10 -> 1.08. Settling the let-go too (the ease while the lock lets go) raised
    # an active turning walk's jerk 1.085 -> 1.123 and its largest one-frame jerk 1.43 ->
    # 1.70x the input's; only the blend-in leaves both as they were. (Scratch figures:
    # runs/settle/shape_in.py; the panel's in the model card, "A landing foot settles".)
    stance_settle: bool = False
    # ...and whether, through an offline clip's mirrored lead-in (``StanceOffset.free_until``),
    # a fully locked foot takes the mean of the restyled offsets over its contact so far
    # (False: the last lead-in frame's, one frame of a stance that wanders). A standing take
    # keeps that stance throughout: towards youthful a held-out left-hand wave's ankles stood
    # 14.1 cm apart with the last frame's (the input's 14.2, a live stream's 17.5, real
    # youthful waves' 22.6-25.1), 17.4 with the mean; youthful read 61.5 -> 71.4 % on the
    # worst judge, active and feminine's standing actions less (the model card, "The stance
    # a standing take starts in").
    stance_lead_mean: bool = False
    # ...and the share of the stance's place (the offset, not the turn) kept while the
    # performer stands: it rises to all of it between STANDING_SPEED and MOVING_SPEED of the
    # input's low-passed speed over ground (pace_tau), so walks and runs keep their restyled
    # stance whatever this is; the restyler's ``standing_stance`` sets it for its style mix.
    # The multistyle model's standing stance towards active is wider than any real active
    # take's (raises and waves 17.7-21.6 cm against real 14.4-17.3; the performer's own 14.3
    # to 15.2 lies inside): on the input's ankles standing, its raises read active 51-85 ->
    # 81-90 % on the judges' mean (the model card, "Active stands as the performer stands").
    stance_standing: float = 1.0
    # ...and the foot's turn about the vertical against the input's (toes out or in):
    # at most this many degrees, moving at most this fast while locked (degrees a frame;
    # 0.04 would move the ball of a 15 cm foot 0.01 cm).
    turn_cap: float = 30.0
    turn_rate: float = 0.0
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
    # ...and the share per centimetre of its own step by which a foot in the air takes back
    # what its shift lags the body's, beside the slowed share of its steps (``Pace``; a
    # planted foot keeps the shift it landed with): a turn or a change of pace leaves some.
    # Per centimetre, so that a foot lifting slowly is not pulled back (0.05 a frame
    # pulled it back by 0.5 cm a frame at lift-off, where the stance's lag is largest;
    # tests/test_pace.py). Until 2026-11-30 a free foot went with the body's steps and
    # took the lag back at 0.15 a frame.
    carry_rate: float = 0.01
    # Where a foot off the floor goes: False, where the restyled leg swings it (moved by the
    # pace's lag); True, along the input's own ankle path, less the foot's pace shift and
    # lowered with the hips (the restyled leg still bends its knee its own way and turns its
    # foot). On the input's path a swing keeps the performer's one-humped speed: the
    # restyled swing of the multistyle model towards elderly and exhausted rose high and
    # late, and the input lock's 4-frame release crossed the gap to it (100 % and 96 % of
    # held-out swings dipped mid-swing, 3 % and 7 % on the input's path, and both read more
    # as the style: the model card, "Swings on the input's path"). The pair model's own swing
    # is what reads exhausted (walks 93 -> 52 % on the worst judge on the input's path).
    swing_path: bool = False
    # Gait amplitude (``GaitAmplitude``): points (input speed over ground in cm/frame, gain)
    # of how far the style swings its arms (``arm_swing``) and lifts and drops its hips
    # (``hips_bob``) against the performer's, joined by straight lines from (0, 1)
    # (standing: waves and raises are left alone) and held beyond the last; () = the
    # input's own. The input's speed is low-passed over pace_tau frames; an arm bone's swing
    # is its motion about a low-pass of the input's rotations, the hips' bob their height
    # about a low-pass of the output's, both over amplitude_tau frames (a quarter of a
    # second: a triple pole passes 15 % of a 1 Hz walk's swing into the mean, 8 % of a run's).
    arm_swing: tuple[tuple[float, float], ...] = ()
    hips_bob: tuple[tuple[float, float], ...] = ()
    # ...and points (input speed, the share of the output's own swing of the hands across
    # the body kept; the rest is replaced by a share of the input's: ``amplitude.py``'s
    # ACROSS_INPUT_SHARE) for the styles whose own across swing reads as another action.
    arm_across: tuple[tuple[float, float], ...] = ()
    # ...and points (input speed, gain) of a raised hand's sway across the body: the part of
    # a hand's across place above its low-pass scaled, for a hand held over its elbow, by the
    # styles whose waves (``wave_sway``: where the performer's hand sways) or raises
    # (``raise_sway``: where it does not) sway further or less than the restyle's; the first
    # point is at speed 0 (standing), so they fade out as the performer walks.
    wave_sway: tuple[tuple[float, float], ...] = ()
    raise_sway: tuple[tuple[float, float], ...] = ()
    # ...and (input speed, share, degrees) of how far the elbows bend on average: the share of
    # the way from the output's own bend (its low-pass) to the style's, none standing (the
    # arms are the action of a wave or a raise), straight lines between the points.
    elbow_bend: tuple[tuple[float, float, float], ...] = ()
    # ...and (input speed, share, degrees) of how far forward of straight down the hands are
    # carried from the shoulders (``models.metrics.arm_forward``), the same way: the share of
    # the way from the output's own low-passed place to the style's, the upper arms turned
    # about the level axis across the body, none standing.
    arm_forward: tuple[tuple[float, float, float], ...] = ()
    # ...and (input speed, share) of a still hanging arm's motion taken away (``still``): where
    # the performer's hand hangs still, the share of the way from the output arm's offset
    # from the input's to its low-pass (the restyle's posture, without the generator's own
    # motion about it).
    still_arms: tuple[tuple[float, float], ...] = ()
    # ...and (input speed, share) of a waving arm's own motion taken away (``still``): where
    # the performer's raised hand sways across, the same share of the way to the low-pass.
    waving_arms: tuple[tuple[float, float], ...] = ()
    # ...and (input speed, share) of a waving arm's elbow bend given back to the performer
    # (``still``): where the waving hold holds an arm, its elbow's flexion goes the share of
    # the way from the restyle's posture to the performer's own, whose forearm carries the wave.
    waving_elbows: tuple[tuple[float, float], ...] = ()
    # ...and (input speed, share, degrees) of how far the knees bend on average: each knee's
    # flexion scaled so its low-pass goes the share of the way from the output's own bend to
    # the style's (its swing scaled with it), none standing.
    knee_bend: tuple[tuple[float, float, float], ...] = ()
    # ...and (input speed, share, degrees) of how far forward of straight down the upper arms
    # point (``across.elbow_forward_angle``, in the shoulders' frames), the same way: the share
    # of the way from the output's own low-passed angle to the style's, the upper arms turned
    # about the level axis across the body, none standing.
    elbow_forward: tuple[tuple[float, float, float], ...] = ()
    # ...and (input speed, share) of the way from the output's low-passed lean across (the line
    # from the spine's joint to the head, ``lean.spine_lean``) to the input's, the spine turned
    # about the hips' level forward axis, none standing.
    performer_lean: tuple[tuple[float, float], ...] = ()
    amplitude_tau: float = 15.0


# Where planted feet go (``--feet``). "input": on the input's own ankles, turned as the
# input's; a pair model keeps it unless its checkpoint names another. "stance": beside
# them, where the restyled legs stand, turned as restyled (the knees bend as restyled in
# both). The multi-style model reads most as its targets so (78.5 % on the judges' mean
# over six against 57.8 %), but for elderly and exhausted (its ``feet_of_style``). For the
# pair default "input" reads better since its hips follow within 2 frames (88.1 % against
# 75.4 % on the judges' mean, action 89.5 against 86.8 %, measured when a planted foot
# still crept into a new stance: ``stance_rate``). The stance's hips settle slower (8
# frames): with 2 the multistyle model read feminine 79.6 -> 55.5 % (its walks 91 -> 2 %)
# and popped more in five styles of six, though active, elderly, exhausted and masculine
# gained 7-16 points; masculine asks for 2 (``pelvis_quick_share``: on both panels 66.6 ->
# 86.1 % and 66.0 -> 72.2 % on the worst judge, its worst pop 2.75 -> 3.15x the input's)
# and active for half of it (60.6 -> 68.8 % and 70.5 -> 75.1 %; all of it put active's jerk
# over its bar).
# "auto", the default, takes the model's own (``Restyler.feet``; figures in
# models/checkpoints/MODEL_CARD.md).
# The stance's cap (measured when a foot's offset was frozen where its lock starts to blend
# in, ``ramp`` frames before touch-down, while the restyled foot still swings; it now
# settles, ``stance_settle``): a large one is mostly swing: with 15 cm the multistyle
# model's knees popped 3.1-4.0x the input's largest jerk in active, feminine, masculine and
# youthful walks and runs; 8 cm: 1.95-3.11x, every style read as its target within a point
# of 15 cm's (5 cm: feminine -2.0). Following the restyled foot at full speed until full
# contact popped more (6.6x, a feminine run): the offset then stops dead, where settling
# eases it to a stop.
# The stance lets go over 8 frames: its planted foot stands up to the cap from the input's
# while the restyled swing foot is elsewhere again by lift-off, and over 4 frames the foot
# jumped that gap (the multistyle model's held-out active walks: a toe's one-frame jerk 5x
# the input's; active's jerk ratio 1.132 over held-out takes, 1.093 over 8 frames, youthful
# 1.081 -> 1.056; for 4 points of active's style on the worst conv judge, the others within a
# point or better: the model card's "The stance lets go over 8 frames"). The input lock keeps
# 4: with 8 the pair default read exhausted 0.8 points less on its worst conv judge, where
# it stands at the bar (its jerk was 1.008 already).
# "path": the input lock, and the feet in the air on the input's own path too
# (``swing_path``); the multistyle model's for elderly and exhausted.
# The input's low-passed speed over ground (cm/frame) at and below which a performer stands,
# and from which they move (``stance_standing``): held-out normal raises and waves move
# their root at most 0.13 cm a frame (p99), walks at least 1.25 (p10).
STANDING_SPEED, MOVING_SPEED = 0.3, 0.9

FEET = {"input": ContactSettings(),
        "stance": ContactSettings(stance_cap=8.0, pelvis_tau=8.0, release=8, stance_settle=True,
                                  stance_lead_mean=True),
        "path": ContactSettings(swing_path=True)}
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


def quick_hips_of(restyler, weights=None) -> float:
    """``ContactSettings.pelvis_quick_share`` with ``restyler`` (towards the style mix
    ``weights``, where it takes one): 0 for a restyler that asks for none."""
    if not hasattr(restyler, "quick_hips"):
        return 0.0
    return float(restyler.quick_hips(weights))


def stance_standing_of(restyler, weights=None) -> float:
    """``ContactSettings.stance_standing`` with ``restyler`` (towards the style mix
    ``weights``, where it takes one): 1 (all of the stance) for a restyler that asks for no less."""
    if not hasattr(restyler, "standing_stance"):
        return 1.0
    return float(restyler.standing_stance(weights))


# ``amplitudes_of`` for a restyler that adds no gait amplitude: the input's own.
NO_AMPLITUDES = {"arm_swing": (), "hips_bob": (), "arm_across": (), "wave_sway": (), "raise_sway": (),
                 "elbow_bend": (), "arm_forward": (), "still_arms": (), "waving_arms": (),
                 "waving_elbows": (), "knee_bend": (), "elbow_forward": (), "performer_lean": ()}


def amplitudes_of(restyler, weights=None) -> dict:
    """``ContactSettings.arm_swing``, ``hips_bob``, ``arm_across``, ``wave_sway``, ``raise_sway``,
    ``elbow_bend``, ``arm_forward``, ``still_arms``, ``waving_arms``, ``waving_elbows``, ``knee_bend``,
    ``elbow_forward`` and ``performer_lean``, by name, with ``restyler`` (towards the style mix
    ``weights``, where it takes one): () each for a restyler without them."""
    if not hasattr(restyler, "amplitudes"):
        return dict(NO_AMPLITUDES)
    return {name: tuple(points) for name, points in restyler.amplitudes(weights).items()}


def feet_for(name: str, restyler=None, pace: str = "style") -> ContactSettings:
    """``--feet NAME`` and ``--pace`` (checked beforehand) for ``restyler``: "auto" takes
    the model's own lock."""
    if name == AUTO_FEET:
        name = getattr(restyler, "feet", "input")
    styled = {"pace": pace_of(restyler, pace), "pelvis_quick_share": quick_hips_of(restyler),
              "stance_standing": stance_standing_of(restyler), **amplitudes_of(restyler)}
    styled = {key: value for key, value in styled.items() if value != getattr(FEET[name], key)}
    return replace(FEET[name], **styled) if styled else FEET[name]
