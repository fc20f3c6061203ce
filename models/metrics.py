"""Motion-quality measures on world joint positions (what a viewer sees), for
``stylecast eval``. Pure numpy on arrays; each is checked in tests/test_metrics.py on
synthetic motion with a known answer (a jittered copy raises jerk, a sliding foot raises
the slide, an identity restyle scores the input's values, ...).

Positions are (T, J, 3) in centimetres at 60 fps from forward kinematics of the humanoid
(``world_positions``). Joint groups name the humanoid bones whose joints they average.

* jerk: the third difference of positions, |p_t - 3 p_{t-1} + 3 p_{t-2} - p_{t-3}|, per
  frame and joint (cm/frame^3). High-frequency shake shows here long before it shows in
  the paper's first-difference smoothness, which is why both are reported.
* planted feet (``planted``): the INPUT's foot is low (within ``PLANT_HEIGHT`` of the
  lowest that joint goes in the clip) and nearly still (below ``PLANT_SPEED``). This is
  deliberately a different, simpler test from the foot lock's own contact detector
  (``motion.footlock``), so the instrument does not share the fixer's blind spots.
* slide: horizontal speed (cm/frame) of a foot joint of a motion in the frames where the
  input's foot is planted.
* holds (``held``, ``hold_samples``): where the INPUT holds a hand or the head still
  against the hips (below ``HOLD_SPEED`` for at least ``HOLD_FRAMES`` frames in a row), how
  fast the output's moves there. A performer who holds a pose expects the avatar to hold it;
  a slow drift of the correction moves a held hand by centimetres while jerk, which sees only
  fast changes, stays at the input's.
* step height (``step_heights``): how high each ankle rises above where it stands in a
  take (its 98th-percentile height over its 5th), against the input's, and real target
  takes' against real source takes'. An elderly walk shuffles (real held-out elderly walks
  step 11.0 cm, normal ones 14.0); a restyle that bends the swing leg more steps higher, which
  no other measure here and no judge flagged (the multistyle model towards elderly: 18.6 cm).
* gait statistics (``GAIT_STATISTICS``): a take's hips twist (how far the hips' facing
  swings about its one-second mean, degrees), stance width (the ankles' mean distance
  apart across the hips' facing, signed so crossed feet count against it, cm), arm swing
  (how far the hands swing forward and back about their one-second mean, against the hips,
  cm), arm swing across (the same across the body while the hands hang, cm) and a raised
  hand's sway (how far a hand held over its elbow sways across the body about its
  one-second mean, cm: a wave's, which a raise lacks), read against the range of real takes
  of the target style and the same action, widened by each statistic's tolerance
  (``eval_measures.gait_outside``). Each is something a viewer sees and a judge may not
  weigh: the multistyle model towards active twisted
  held-out walks' hips 12.2 degrees, past every real active walk (5.4-8.7; the judges read
  70 % of those windows as turning walks), and its stance lock towards feminine planted
  the walks' ankles 3.6 cm apart, crossing in 3-9 % of frames, where real feminine walks
  keep 8.0-11.5 (until a landing foot's stance settled: 4.8 cm, no longer crossing).
* swing dips (``swing_dips``): whether an ankle's horizontal speed keeps one hump through
  each swing of the motion's own feet, as real walks' do (a second hump is a foot that
  jumps or stalls in the air).
* floor penetration: how far a foot joint of the output sinks below the lowest the same
  joint goes in the input (the input's floor contact), per frame.
* timing sync: Pearson correlation of per-frame body speed (mean over joints of speed
  relative to the hips, so the shared root path cannot inflate it), input vs output.
* off the hinge (``off_hinge``): how far an elbow or knee of a pose is from one a hinge can
  make (``motion.hinges``: the data's elbows and knees bend about one axis, one way),
  measured on the bone's own axes, apart from the fixer's swing-twist split: a lower
  arm's direction out of the plane it flexes in, a lower leg's flexion axis turned off
  itself (a sideways bend or a twist), and either bent past straight. Degrees per frame,
  the worst hinge bone's.
* Frechet distance between two sets of feature vectors (Gaussian fit), as in FID and
  seed 003's motion FID, with its mean part apart, sample weights to match a label mix
  (``mix_weights``), and a scale-free gap between two sets' means (``feature_gap``) for
  sets too small for a covariance.
* tempo (``tempo``): the dominant frequency of a take's joints against its hips, for the
  ceiling of a restyle that keeps the performer's timing (``ceilings``).
* travel speed (``travel_speed``, ``with_travel_speed``): the root's mean horizontal speed,
  and a root path rescaled to another speed, for the ceiling of a restyle that keeps the
  input's travel (``eval``).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np

from stylecast.motion.clip import Clip, forward_kinematics
from stylecast.motion.humanoid import HUMANOID_BONES

FOOT_JOINTS = {"left": ("LeftFoot", "LeftToes"), "right": ("RightFoot", "RightToes")}
JOINT_GROUPS: dict[str, tuple[str, ...]] = {
    "all": HUMANOID_BONES,
    "hands": ("LeftHand", "RightHand"),
    "arms": ("LeftUpperArm", "LeftLowerArm", "RightUpperArm", "RightLowerArm"),
    "head": ("Neck", "Head"),
    "spine": ("Hips", "Spine", "Chest", "UpperChest"),
    "feet": ("LeftFoot", "LeftToes", "RightFoot", "RightToes"),
    "knees": ("LeftLowerLeg", "RightLowerLeg"),
}
PLANT_HEIGHT = 3.0  # cm above the lowest the joint goes in the clip
PLANT_SPEED = 0.5  # cm per frame at 60 fps (30 cm/s)
# cm above the lowest a foot joint goes: the band ``skate_samples`` reads a foot in as on
# (or at) the floor, whatever it does after; an ankle in a held-out normal walk's swing
# passes 10-15 cm up, its heel-strike and toe-off within 5.
SKATE_HEIGHT = 5.0
HOLD_JOINTS = ("LeftHand", "RightHand", "Head")
# cm per frame at 60 fps (9 cm/s) against the hips: a hand held up in a held-out raise moves
# 0.06 cm a frame on average, a raising or waving hand 1-4.
HOLD_SPEED = 0.15
# ...for at least this many frames in a row (a sixth of a second at 60 fps): a hold, not the
# frame or two in which a swinging hand turns or a walking head bobs through its top. Counted
# frame by frame, those turns made a copy of each held-out normal take one frame late, which
# holds nothing less than its input, score 1.10x the input's holds (walks 1.25-1.26x, runs
# 2.19x; two frames late 1.20x, walks 1.50-1.52x, over the 1.5 goal): the measure read a
# restyle's timing as drift. Held 10 frames: 1.02x (walks 1.11-1.13x), two frames late 1.05x
# (the model card, "A hold lasts a sixth of a second"). A held-out raise holds its hand up for
# 20-30 frames (median), the head through a wave for hundreds; a walking head stays under the
# speed for 4 frames at a time (median).
HOLD_FRAMES = 10


def _index(names) -> list[int]:
    return [HUMANOID_BONES.index(n) for n in names]


def world_positions(rotations: np.ndarray, roots: np.ndarray, skeleton) -> np.ndarray:
    """Humanoid local rotations (T, J, 4) and root path (T, 3) -> joint positions (T, J, 3)."""
    clip = Clip(skeleton, np.asarray(rotations, np.float64), np.asarray(roots, np.float64), 60.0)
    return forward_kinematics(clip)[0]


def jerk(positions: np.ndarray) -> np.ndarray:
    """(T, J, 3) -> (T-3, J) magnitude of the third difference."""
    return np.linalg.norm(np.diff(positions, n=3, axis=0), axis=-1)


def off_hinge(rotations: np.ndarray) -> np.ndarray:
    """Humanoid local rotations (T, J, 4) -> (T,) degrees the worst elbow or knee of each
    frame is off its hinge (the module docstring): 0 for any pose the data's joints make."""
    from scipy.spatial.transform import Rotation

    from stylecast.motion.hinges import HINGES

    q = np.asarray(rotations, np.float64)
    worst = np.zeros(len(q))
    for hinge in HINGES:
        r = Rotation.from_quat(q[:, HUMANOID_BONES.index(hinge.bone)])
        bone, flex = np.eye(3)[hinge.axis], np.eye(3)[hinge.flexion]
        if hinge.twists:  # the bone may turn about itself: only its direction is bound
            sideways = np.arcsin(np.clip(np.abs(r.apply(bone) @ flex), 0.0, 1.0))
        else:  # nothing but the flexion: its axis must stay where it is
            sideways = np.arccos(np.clip(r.apply(flex) @ flex, -1.0, 1.0))
        pointing = r.apply(bone)
        bend = np.arctan2(np.cross(bone, pointing) @ flex, pointing @ bone)
        past_straight = np.maximum(-hinge.bent * bend, 0.0)
        worst = np.maximum(worst, np.degrees(np.maximum(sideways, past_straight)))
    return worst


def peak_jerk_ratio(jerk_in: np.ndarray, jerk_out: np.ndarray) -> float:
    """``jerk`` of the input and of the output -> the output's largest jerk of any joint in
    any frame over the input's: a pop (one frame where a foot or a knee snaps) hardly moves
    the mean jerk of a clip, this it doubles (a stance turn of 54 degrees in one frame read
    1.74 here, 1.01 on the mean)."""
    return float(jerk_out.max() / max(jerk_in.max(), 1e-12))


def group_means(per_joint: np.ndarray) -> dict[str, float]:
    """Mean over frames and the joints of each group of a (T, J) array."""
    return {g: float(per_joint[:, _index(names)].mean()) for g, names in JOINT_GROUPS.items()}


def planted(positions: np.ndarray) -> dict[str, np.ndarray]:
    """Per foot, boolean (T-1,) over frame pairs: the foot (either of its joints) is low
    and nearly still from frame t-1 to t."""
    out = {}
    for side, names in FOOT_JOINTS.items():
        masks = []
        for j in _index(names):
            height = positions[:, j, 1] - positions[:, j, 1].min()
            speed = np.linalg.norm(np.diff(positions[:, j], axis=0), axis=-1)
            masks.append((height[1:] < PLANT_HEIGHT) & (height[:-1] < PLANT_HEIGHT) & (speed < PLANT_SPEED))
        out[side] = np.logical_or.reduce(masks)
    return out


def horizontal_speed(positions: np.ndarray, joint: str) -> np.ndarray:
    """(T, J, 3) -> (T-1,) horizontal (x, z) distance a joint moves per frame."""
    j = HUMANOID_BONES.index(joint)
    return np.linalg.norm(np.diff(positions[:, j][:, [0, 2]], axis=0), axis=-1)


def slide_samples(positions: np.ndarray, masks: dict[str, np.ndarray]) -> np.ndarray:
    """Horizontal speeds of both joints of each foot over that foot's planted frames
    (of the input: ``masks`` from ``planted(input)``), concatenated."""
    parts = [horizontal_speed(positions, j)[masks[side]] for side, names in FOOT_JOINTS.items() for j in names]
    return np.concatenate(parts)


def skate_samples(positions: np.ndarray) -> np.ndarray:
    """Foot skating read on the motion's OWN contacts, never the input's: per frame pair
    and foot joint (ankle and ball of each foot), the horizontal distance moved while the
    joint is within SKATE_HEIGHT of the lowest it goes in the clip, weighted by
    2 - 2^(h / SKATE_HEIGHT) (1 on the floor, 0 at the band's top: Zhang et al.'s skating
    measure, 2018), 0 elsewhere. (T-1) x 4 samples, so an output and its input compare by
    their means. ``slide_samples`` cannot see a heel dragged along the floor before the
    input's foot lands (the input is not planted yet); this can."""
    parts = []
    for names in FOOT_JOINTS.values():
        for j in _index(names):
            height = positions[:, j, 1] - positions[:, j, 1].min()
            h = np.maximum(height[1:], height[:-1])
            speed = np.linalg.norm(np.diff(positions[:, j][:, [0, 2]], axis=0), axis=-1)
            parts.append(np.where(h < SKATE_HEIGHT, (2.0 - 2.0 ** (h / SKATE_HEIGHT)) * speed, 0.0))
    return np.concatenate(parts)


# A swing (``swing_dips``): a run of frame pairs in which the motion's OWN foot is not
# planted (``planted`` of the motion itself), at least SWING_FRAMES long, inside the take.
# A dip: a local minimum of the ankle's horizontal speed under DIP_DEPTH of the lower of the
# highest speeds before and after it in the swing, both at least DIP_PEAK of the swing's
# top (a wobble at a swing's slow ends is not one). Real walks have none: 0 of 777 held-out
# swings of walks and turning walks over all seven styles; real runs 0-99 % by style (a
# heel kicked up behind: active 99 %, elderly none), so the figure is read against real
# takes of the style and the action. The foot lock made one in every swing of the
# multistyle model's held-out walks made elderly: its input lock let a lifting foot go
# over 4 frames, crossing the gap to the restyled swing in those frames, and the pace's
# lag was taken back at 15 % a frame as it lifted (a slump to 40 of the input's 210 cm/s;
# MODEL_CARD.md, "Swings that dip"; since "Swings on the input's path", 3 %). No other
# measure here flagged it.
SWING_FRAMES = 8
DIP_DEPTH = 0.75
DIP_PEAK = 0.3


def swing_dips(positions: np.ndarray) -> np.ndarray:
    """(T, J, 3) -> per swing of either ankle (``STEP_JOINTS``) in the take, in order, 1 where
    its horizontal speed dips mid-swing and 0 where it keeps one hump (see SWING_FRAMES)."""
    out, masks = [], planted(positions)
    for side, ankle in zip(FOOT_JOINTS, STEP_JOINTS):
        speed, free = horizontal_speed(positions, ankle), ~masks[side]
        edges = np.flatnonzero(np.diff(np.concatenate([[0], free.astype(np.int8), [0]])))
        for start, end in zip(edges[::2], edges[1::2]):
            if end - start < SWING_FRAMES or start == 0 or end == len(free):
                continue
            out.append(float(_dips(speed[start:end]) > 0))
    return np.array(out)


def _dips(v: np.ndarray) -> int:
    """How many dips one swing's speeds (n,) have (``swing_dips``)."""
    before, after = np.maximum.accumulate(v), np.maximum.accumulate(v[::-1])[::-1]
    inner = np.arange(1, len(v) - 1)
    low = (v[inner] <= v[inner - 1]) & (v[inner] <= v[inner + 1])
    sides = np.minimum(before[inner - 1], after[inner + 1])
    return int(np.count_nonzero(low & (v[inner] < DIP_DEPTH * sides) & (sides >= DIP_PEAK * v.max())))


STEP_JOINTS = ("LeftFoot", "RightFoot")  # the ankles
STEP_PERCENTILES = (5.0, 98.0)  # where it stands, and how high it steps (not its single highest frame)


def step_heights(positions: np.ndarray) -> np.ndarray:
    """(T, J, 3) -> (2,) cm: each ankle's step height in the take, the 98th percentile of
    its height over its 5th (about 0 for a foot that stays on the floor)."""
    low, high = np.percentile(positions[:, _index(STEP_JOINTS), 1], STEP_PERCENTILES, axis=0)
    return high - low


# Seconds of the running mean the swinging statistics are read about (a gait cycle is
# 0.7-1.2 s in the data): what is left is the swing, not the take's turns or drift.
GAIT_MEAN_SECONDS = 1.0


def _about_running_mean(x: np.ndarray, fps: float = 60.0) -> np.ndarray:
    """(T, ...) -> x less its centred running mean over ``GAIT_MEAN_SECONDS``, on the frames
    where a whole window fits (a take shorter than that: x less its mean)."""
    n = int(round(GAIT_MEAN_SECONDS * fps))
    if len(x) < n:
        return x - x.mean(axis=0)
    c = np.cumsum(np.concatenate([np.zeros((1, *x.shape[1:])), x], axis=0), axis=0)
    mean = (c[n:] - c[:-n]) / n  # windows starting at 0 .. T-n
    return x[n // 2: n // 2 + len(mean)] - mean


def hips_yaw(rotations: np.ndarray) -> np.ndarray:
    """(T, J, 4) -> (T,) the hips' facing about the vertical, radians, unwrapped
    (``representation.word_heading`` of each frame)."""
    from .representation import word_heading

    return np.unwrap(word_heading(np.asarray(rotations, np.float64)[:, None]))


def _across_and_along(yaw: np.ndarray, positions: np.ndarray, joint: str) -> tuple[np.ndarray, np.ndarray]:
    """A joint's position against the hips in the hips' facing ``yaw`` (T,): (T,) across
    (towards the humanoid's left) and (T,) along (forward), cm."""
    rel = positions[:, HUMANOID_BONES.index(joint)] - positions[:, 0]
    across = np.cos(yaw) * rel[:, 0] - np.sin(yaw) * rel[:, 2]
    along = np.sin(yaw) * rel[:, 0] + np.cos(yaw) * rel[:, 2]
    return across, along


def hips_twist(yaw: np.ndarray, positions: np.ndarray) -> float:
    """Degrees: the standard deviation of the hips' facing ``yaw`` about its running mean."""
    return float(np.degrees(_about_running_mean(yaw)).std())


def stance_width(yaw: np.ndarray, positions: np.ndarray) -> float:
    """cm: the left ankle's mean distance from the right across the hips' facing (negative
    while they are crossed)."""
    left, _ = _across_and_along(yaw, positions, "LeftFoot")
    right, _ = _across_and_along(yaw, positions, "RightFoot")
    return float(np.mean(left - right))


def arm_swing(yaw: np.ndarray, positions: np.ndarray) -> float:
    """cm: the hands' forward-and-back swing against the hips, the standard deviation about
    its running mean, averaged over the two hands."""
    return float(np.mean([_about_running_mean(_across_and_along(yaw, positions, hand)[1]).std()
                          for hand in ("LeftHand", "RightHand")]))


# A hand counts as raised while it is this far above its own elbow (cm): the forearm points
# up, as in every real wave and raise (real feminine ones hold the hand at the shoulder, about
# 19 cm over the elbow); a walk's or a run's hands never are.
RAISED_HAND_CM = 10.0


def _hand_sways(yaw: np.ndarray, positions: np.ndarray, raised: bool, fps: float) -> list[float]:
    """cm: each hand's sway across the body against the hips, the standard deviation of its
    across position about its running mean, over the frames it is raised (``raised``: held
    ``RAISED_HAND_CM`` over its elbow) or hangs (not so), for each hand that is so for
    ``GAIT_MEAN_SECONDS`` in all."""
    n = int(round(GAIT_MEAN_SECONDS * fps))
    sways = []
    for hand, elbow in (("LeftHand", "LeftLowerArm"), ("RightHand", "RightLowerArm")):
        up = positions[:, HUMANOID_BONES.index(hand), 1] - positions[:, HUMANOID_BONES.index(elbow), 1] > RAISED_HAND_CM
        frames = up if raised else ~up
        if frames.sum() < n:
            continue
        sway = _about_running_mean(_across_and_along(yaw, positions, hand)[0], fps)
        centred = frames[n // 2: n // 2 + len(sway)] if len(sway) < len(frames) else frames  # as the running mean
        if centred.any():
            sways.append(float(sway[centred].std()))
    return sways


def raised_hand_sway(yaw: np.ndarray, positions: np.ndarray, fps: float = 60.0) -> float:
    """cm: how far a raised hand sways across the body (``_hand_sways``), the busier hand's; 0
    where no hand is raised for ``GAIT_MEAN_SECONDS`` (a walk). A wave is this sway: real
    youthful waves sway 1.5x as far as normal ones, elderly ones 0.6x and feminine ones 0.2x
    (1.6 cm, no more than their raises), and the judges read a wave by it (the multistyle
    model towards youthful swayed its held-out waves of both hands 0.7x as far as the input,
    and they read as raises)."""
    return max(_hand_sways(yaw, positions, True, fps), default=0.0)


def arm_swing_across(yaw: np.ndarray, positions: np.ndarray, fps: float = 60.0) -> float:
    """cm: how far the hands swing across the body while they hang (``_hand_sways``, not
    raised), averaged over the two hands; 0 where neither hangs for ``GAIT_MEAN_SECONDS``.
    Real walks swing the hands across 0.6-1.3 cm (elderly) to 7.1-10.7 (active); the
    multistyle model towards youthful swung its held-out walks' 6.7-7.7 cm across, an active
    walk's arms, where real youthful walks swing 2.2-3.8 (``arm_swing`` reads only forward
    and back)."""
    sways = _hand_sways(yaw, positions, False, fps)
    return float(np.mean(sways)) if sways else 0.0


def elbow_bend(yaw: np.ndarray, positions: np.ndarray) -> float:
    """Degrees: how far the elbows bend, the angle between the upper arm (shoulder joint to
    elbow) and the forearm (elbow to wrist), 0 straight, the mean over frames and both arms;
    NaN where an arm has no length (a synthetic take). Read from the joints' positions, apart
    from the stream's hinge code (``motion.hinges``). Real runs bend them by style (each
    take's mean): feminine 49-61 degrees, active 51-91, exhausted 99-113, youthful 28-37,
    normal 77-105; the multistyle model's held-out runs restyled towards the first four bent
    them 38, 104, 73 and 50 on average (2026-12-07)."""
    return _mean_bend(positions, (("LeftUpperArm", "LeftLowerArm", "LeftHand"),
                                  ("RightUpperArm", "RightLowerArm", "RightHand")))


def knee_bend(yaw: np.ndarray, positions: np.ndarray) -> float:
    """Degrees: how far the knees bend, the angle between thigh (hip joint to knee) and shin
    (knee to ankle), 0 straight, the mean over frames and both legs (``elbow_bend``'s reading;
    the table of ``gait_amplitude.KNEE_BENDS``; not one of ``GAIT_STATISTICS``). Real feminine
    walks and runs bend them less than normal ones (the training clips: 31.3 and 49.1 degrees
    against 34.9 and 57.9); the multistyle model towards feminine bent the held-out normal
    walks' and runs' more (37.5 and 61.6, the input's 34.9 and 58.5), and the judges read
    those runs feminine in a third of windows (2026-12-07)."""
    return _mean_bend(positions, (("LeftUpperLeg", "LeftLowerLeg", "LeftFoot"),
                                  ("RightUpperLeg", "RightLowerLeg", "RightFoot")))


def _mean_bend(positions: np.ndarray, chains) -> float:
    """Degrees: the mean over frames and ``chains`` (upper, lower, end joint names) of the
    angle between the upper and the lower bone; NaN where a bone has no length."""
    angles = []
    for upper, lower, end in chains:
        a = positions[:, HUMANOID_BONES.index(lower)] - positions[:, HUMANOID_BONES.index(upper)]
        b = positions[:, HUMANOID_BONES.index(end)] - positions[:, HUMANOID_BONES.index(lower)]
        if np.any(np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1) < 1e-9):
            return float("nan")
        # atan2 of the cross and dot products: accurate near straight, where arccos of the
        # cosine loses half the digits (as ``rotations.angle_between``)
        angles.append(np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))))
    return float(np.mean(angles))


def arm_forward(yaw: np.ndarray, positions: np.ndarray) -> float:
    """Degrees: how far forward of straight down each hand sits from its shoulder joint (the
    upper arm's), in the hips' facing ``yaw`` (T,): the angle of the joint-to-hand line in
    the plane of forward and up, the mean over frames and both arms (the table of
    ``gait_amplitude.ARM_FORWARDS``; not one of ``GAIT_STATISTICS``). Real active walks carry
    the hands 19.0-30.6 degrees forward (each take's mean), the held-out normal walks 13.1;
    the multistyle model's walks towards active held them back (5.7)."""
    angles = []
    for upper, hand in (("LeftUpperArm", "LeftHand"), ("RightUpperArm", "RightHand")):
        rel = positions[:, HUMANOID_BONES.index(hand)] - positions[:, HUMANOID_BONES.index(upper)]
        along = np.sin(yaw) * rel[:, 0] + np.cos(yaw) * rel[:, 2]
        angles.append(np.degrees(np.arctan2(along, -rel[:, 1])))
    return float(np.mean(angles))


def hips_bob(positions: np.ndarray) -> float:
    """cm: the hips' rise and fall, the standard deviation of their height about its running
    mean (the table of ``gait_amplitude.HIPS_BOBS``; not one of ``GAIT_STATISTICS``)."""
    return float(_about_running_mean(np.asarray(positions, np.float64)[:, 0, 1]).std())


class GaitStatistic(NamedTuple):
    """``read``: (the hips' facing (T,) from ``hips_yaw``, positions (T, J, 3)) -> one
    figure per take.
    ``tolerance``: how far past the real takes' range a figure may lie and still count as
    inside, in its own unit: about the spread of one style's takes, and under what a viewer
    sees (a standing take's hips twist 0.1-1.1 degrees; the pair default's right raises,
    0.3 against real exhausted raises' 0.4-1.0, read 1.36x outside without it)."""

    read: Callable[[np.ndarray, np.ndarray], float]
    tolerance: float


GAIT_STATISTICS = {"hips_twist_deg": GaitStatistic(hips_twist, 1.0),
                   "stance_width_cm": GaitStatistic(stance_width, 1.0),
                   "arm_swing_cm": GaitStatistic(arm_swing, 1.0),
                   "arm_swing_across_cm": GaitStatistic(arm_swing_across, 1.0),
                   "raised_hand_sway_cm": GaitStatistic(raised_hand_sway, 1.0),
                   "elbow_bend_deg": GaitStatistic(elbow_bend, 5.0)}


def gait_statistics(rotations: np.ndarray, positions: np.ndarray) -> dict[str, float]:
    """A take's ``GAIT_STATISTICS``, by name (the hips' facing read once for all)."""
    yaw = hips_yaw(rotations)
    return {name: stat.read(yaw, positions) for name, stat in GAIT_STATISTICS.items()}


def floor_penetration(input_positions: np.ndarray, output_positions: np.ndarray) -> np.ndarray:
    """(T,) how far (cm) the lowest foot joint of the output sinks below the lowest height
    that joint reaches in the input (its floor contact), per frame; 0 when above."""
    joints = _index([j for names in FOOT_JOINTS.values() for j in names])
    floor = input_positions[:, joints, 1].min(axis=0)
    return np.maximum(floor - output_positions[:, joints, 1], 0.0).max(axis=1)


def body_speed(positions: np.ndarray) -> np.ndarray:
    """(T, J, 3) -> (T-1,) mean joint speed relative to the Hips."""
    rel = positions - positions[:, :1]
    return np.linalg.norm(np.diff(rel, axis=0), axis=-1).mean(axis=1)


def _speed_from_hips(positions: np.ndarray, joint: str) -> np.ndarray:
    """(T, J, 3) -> (T-1,) distance a joint moves per frame relative to the Hips."""
    rel = positions[:, HUMANOID_BONES.index(joint)] - positions[:, 0]
    return np.linalg.norm(np.diff(rel, axis=0), axis=-1)


def held(positions: np.ndarray, min_frames: int = HOLD_FRAMES) -> dict[str, np.ndarray]:
    """Per ``HOLD_JOINTS`` joint, boolean (T-1,) over frame pairs: it moves less than
    ``HOLD_SPEED`` against the hips from frame t-1 to t, in a run of at least ``min_frames``
    such frame pairs (``HOLD_FRAMES``; 1: every slow frame, the measure before 2026-12-08).
    A morphological opening by a run of ``min_frames`` drops the shorter runs and keeps the
    longer ones whole."""
    from scipy import ndimage

    run = np.ones(max(int(min_frames), 1), bool)
    return {j: ndimage.binary_opening(_speed_from_hips(positions, j) < HOLD_SPEED, structure=run)
            for j in HOLD_JOINTS}


def hold_samples(positions: np.ndarray, masks: dict[str, np.ndarray]) -> np.ndarray:
    """Speeds against the hips of each held joint over its held frames (of the input:
    ``masks`` from ``held(input)``), concatenated."""
    return np.concatenate([_speed_from_hips(positions, j)[mask] for j, mask in masks.items()])


def timing_sync(input_positions: np.ndarray, output_positions: np.ndarray) -> float:
    a, b = body_speed(input_positions), body_speed(output_positions)
    if a.std() < 1e-9 or b.std() < 1e-9:
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])


def frechet_distance(x: np.ndarray, y: np.ndarray, x_weights: np.ndarray | None = None) -> float:
    """Frechet distance between Gaussians fitted to feature sets x (N, D) and y (M, D):
    |mu_x - mu_y|^2 + tr(Sx + Sy - 2 (Sx Sy)^(1/2)). ``x_weights`` (N,): fit x's Gaussian
    to weighted samples (``mix_weights`` gives x the label mix of y)."""
    return frechet_parts(x, y, x_weights)[0]


def frechet_parts(x: np.ndarray, y: np.ndarray, x_weights: np.ndarray | None = None) -> tuple[float, float]:
    """The Frechet distance and its mean part |mu_x - mu_y|^2; the rest is the covariances'
    (a set in the right place but too narrow, too wide or turned)."""
    from scipy import linalg

    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    mu = np.average(x, axis=0, weights=x_weights) - y.mean(axis=0)
    sx, sy = np.cov(x, rowvar=False, aweights=x_weights), np.cov(y, rowvar=False)
    with np.errstate(all="ignore"):
        root = np.real(linalg.sqrtm(sx @ sy))  # rounding can leave a tiny imaginary part
    mean_part = float(mu @ mu)
    return mean_part + float(np.trace(sx) + np.trace(sy) - 2 * np.trace(root)), mean_part


def mix_weights(labels: np.ndarray, reference_labels: np.ndarray) -> np.ndarray:
    """Weights (N,) for samples labelled ``labels`` (integers) that give them the label mix
    of ``reference_labels``: a label's samples share its reference frequency. A label the
    reference lacks weighs 0; one the samples lack cannot be matched, and the others keep
    their relative shares."""
    labels, reference_labels = np.asarray(labels), np.asarray(reference_labels)
    n = max(labels.max(initial=0), reference_labels.max(initial=0)) + 1
    have = np.bincount(labels, minlength=n).astype(np.float64)
    want = np.bincount(reference_labels, minlength=n) / max(len(reference_labels), 1)
    return (want / np.maximum(have, 1.0))[labels]


def feature_gap(x: np.ndarray, y: np.ndarray) -> float:
    """How far the mean of feature set x (N, D) lies from the mean of y (M, D), in y's own
    spread: |mu_x - mu_y| / sqrt(tr Sy), the distance over the root-mean-square distance of
    y's samples from their mean. About 0 for another draw of y, 1 for y moved by one typical
    deviation. Scale-free, so judges' feature spaces can be averaged; and defined for the
    few dozen windows of one action, where a covariance of 64+ dimensions is not."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    spread = np.sqrt(np.sum(np.var(y, axis=0)))
    return float(np.linalg.norm(x.mean(axis=0) - y.mean(axis=0)) / spread) if spread > 0 else float("nan")


def tempo(positions: np.ndarray, fps: float = 60.0, lowest: float = 0.2) -> float:
    """The dominant frequency (Hz) of a take's joints moving against its hips (joint 0): their
    power spectra (Hann window) summed over joints and axes, above ``lowest`` Hz (slow drift).
    A walk's stride, a wave's beat, about one over the length of a one-off raise."""
    rel = np.asarray(positions, np.float64) - np.asarray(positions, np.float64)[:, :1]
    rel = (rel - rel.mean(axis=0)).reshape(len(rel), -1)
    power = np.sum(np.abs(np.fft.rfft(rel * np.hanning(len(rel))[:, None], axis=0)) ** 2, axis=1)
    freqs = np.fft.rfftfreq(len(rel), 1.0 / fps)
    keep = freqs > lowest
    return float(freqs[keep][np.argmax(power[keep])]) if keep.any() else float("nan")


def travel_speed(roots: np.ndarray) -> float:
    """Mean horizontal speed (units per frame) of a root path (T, 3), Y up."""
    step = np.diff(np.asarray(roots, np.float64)[:, [0, 2]], axis=0)
    return float(np.linalg.norm(step, axis=1).mean()) if len(step) else 0.0


def with_travel_speed(roots: np.ndarray, speed: float) -> np.ndarray:
    """The root path (T, 3) with its horizontal displacement from the first frame scaled so
    its mean horizontal speed is ``speed``: the same path shape and timing, covered faster or
    slower; heights untouched. A path that does not move is returned as it is."""
    roots = np.array(roots, np.float64)
    own = travel_speed(roots)
    if own <= 0.0:
        return roots
    roots[:, [0, 2]] = roots[0, [0, 2]] + (roots[:, [0, 2]] - roots[0, [0, 2]]) * (speed / own)
    return roots
