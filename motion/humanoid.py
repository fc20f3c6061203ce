"""Humanoid retargeting: any named rig <-> the canonical humanoid of the source paper.

The canonical humanoid uses Unity ``HumanBodyBones`` names. Its local rotations are
relative to the T-pose in world-aligned bone frames: identity everywhere is a T-pose
facing +Z (the VRM-normalised convention VMC receivers expect).

How the T-pose reference is found (a BVH rest pose, all channels zero, need not be a
T-pose; in the Bandai files every bone points along its local X axis):

1. The source joint mapped to Hips is turned so that its "up" (towards the spine) is +Y
   and its "left" (right hip towards left hip) is +X: this fixes the facing. The spine,
   neck and head joints likewise get "up" along the spine and "left" along the line of
   the shoulders, which fixes their twist (a rig convention bone directions cannot show).
2. Every other mapped joint (the limbs), top-down, is swung by the smallest rotation that points its
   bone (towards the next mapped joint of its chain) along the canonical T-pose
   direction: up the spine, out along +/-X for the arms, down for the legs, forward and
   down for the feet. A bone that must turn by 180 degrees turns about the body's forward
   axis, so limbs stay in the frontal plane instead of flipping knees backwards.
3. Unmapped joints follow their parent (no swing of their own).

The result is each source joint's world rotation in the T-pose, ``tpose_world[j]``; a
humanoid bone's world rotation is then ``world_src[j] * inverse(tpose_world[j])`` which is
identity exactly when the source is in that T-pose. Bone lengths come from the source, so
forward kinematics of the humanoid reproduces the source's joint positions.
"""

from __future__ import annotations

import json
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from . import rotations as rot
from .clip import Clip, forward_kinematics
from .errors import UserError
from .skeleton import Skeleton

# (bone, parent) in topological order: the 22 bones of the paper's VRM humanoid that carry
# motion (the two toe end sites of the paper's 24 carry none).
HUMANOID_HIERARCHY: tuple[tuple[str, str | None], ...] = (
    ("Hips", None),
    ("Spine", "Hips"),
    ("Chest", "Spine"),
    ("UpperChest", "Chest"),
    ("Neck", "UpperChest"),
    ("Head", "Neck"),
    ("LeftShoulder", "UpperChest"),
    ("LeftUpperArm", "LeftShoulder"),
    ("LeftLowerArm", "LeftUpperArm"),
    ("LeftHand", "LeftLowerArm"),
    ("RightShoulder", "UpperChest"),
    ("RightUpperArm", "RightShoulder"),
    ("RightLowerArm", "RightUpperArm"),
    ("RightHand", "RightLowerArm"),
    ("LeftUpperLeg", "Hips"),
    ("LeftLowerLeg", "LeftUpperLeg"),
    ("LeftFoot", "LeftLowerLeg"),
    ("LeftToes", "LeftFoot"),
    ("RightUpperLeg", "Hips"),
    ("RightLowerLeg", "RightUpperLeg"),
    ("RightFoot", "RightLowerLeg"),
    ("RightToes", "RightFoot"),
)
# Bumped whenever the mapping of a given source motion to humanoid rotations changes, so
# caches of retargeted data (models/data.py) and checkpoints can tell.
RETARGET_VERSION = 2

HUMANOID_BONES: tuple[str, ...] = tuple(b for b, _ in HUMANOID_HIERARCHY)
HUMANOID_PARENTS: tuple[int, ...] = tuple(
    -1 if p is None else HUMANOID_BONES.index(p) for _, p in HUMANOID_HIERARCHY
)

# Feet point forward and this far down in the T-pose, so a standing foot (ankle above the
# ball of the foot) reads as identity, as in a VRM model's bind pose. 40 degrees is the
# median ankle-to-toe pitch of standing frames in the Bandai data (39.6).
FOOT_PITCH_DEG = 40.0
_FOOT_DIR = (0.0, -np.sin(np.radians(FOOT_PITCH_DEG)), np.cos(np.radians(FOOT_PITCH_DEG)))
UP, LEFT, FORWARD = np.eye(3)[1], np.eye(3)[0], np.eye(3)[2]

# Canonical T-pose direction of each bone (towards the next bone of its chain).
TPOSE_DIRECTION: dict[str, tuple[float, float, float]] = {
    **{b: (0.0, 1.0, 0.0) for b in ("Hips", "Spine", "Chest", "UpperChest", "Neck", "Head")},
    **{f"Left{b}": (1.0, 0.0, 0.0) for b in ("Shoulder", "UpperArm", "LowerArm", "Hand")},
    **{f"Right{b}": (-1.0, 0.0, 0.0) for b in ("Shoulder", "UpperArm", "LowerArm", "Hand")},
    **{f"{s}{b}": (0.0, -1.0, 0.0) for s in ("Left", "Right") for b in ("UpperLeg", "LowerLeg")},
    "LeftFoot": _FOOT_DIR,
    "RightFoot": _FOOT_DIR,
    "LeftToes": (0.0, 0.0, 1.0),
    "RightToes": (0.0, 0.0, 1.0),
}

# The chain each bone aims along: its direction points at the first mapped bone listed.
_AIM: dict[str, tuple[str, ...]] = {
    "Hips": ("Spine", "Chest", "UpperChest", "Neck"),
    "Spine": ("Chest", "UpperChest", "Neck"),
    "Chest": ("UpperChest", "Neck"),
    "UpperChest": ("Neck",),
    "Neck": ("Head",),
    **{f"{s}{a}": (f"{s}{b}",) for s in ("Left", "Right") for a, b in (
        ("Shoulder", "UpperArm"), ("UpperArm", "LowerArm"), ("LowerArm", "Hand"),
        ("UpperLeg", "LowerLeg"), ("LowerLeg", "Foot"), ("Foot", "Toes"))},
}


def _side_map(template: str, bones: dict[str, str]) -> dict[str, str]:
    out = {}
    for src, dst in bones.items():
        for side, short in (("Left", "L"), ("Right", "R")):
            out[template.format(bone=src, side=side, s=short, lower=side.lower())] = f"{side}{dst}"
    return out


_LIMBS = {"Shoulder": "Shoulder", "UpperArm": "UpperArm", "LowerArm": "LowerArm", "Hand": "Hand",
          "UpperLeg": "UpperLeg", "LowerLeg": "LowerLeg", "Foot": "Foot", "Toes": "Toes"}

# Built-in name maps (source name -> humanoid bone). Names are compared after
# normalisation (case, separators and namespace prefixes such as "mixamorig:" ignored).
BUILTIN_MAPS: dict[str, dict[str, str]] = {
    "unity": {b: b for b in HUMANOID_BONES},
    "bandai": {"Hips": "Hips", "Spine": "Spine", "Chest": "Chest", "Neck": "Neck", "Head": "Head",
               **_side_map("{bone}_{s}", _LIMBS)},
    "vrm": {"J_Bip_C_Hips": "Hips", "J_Bip_C_Spine": "Spine", "J_Bip_C_Chest": "Chest",
            "J_Bip_C_UpperChest": "UpperChest", "J_Bip_C_Neck": "Neck", "J_Bip_C_Head": "Head",
            **_side_map("J_Bip_{s}_{bone}", {**_LIMBS, "ToeBase": "Toes"})},
    "mocap": {"Hips": "Hips", "Spine": "Spine", "Spine1": "Chest", "Spine2": "UpperChest",
              "Chest": "Chest", "Chest2": "UpperChest", "UpperChest": "UpperChest",
              "Neck": "Neck", "Head": "Head",
              **_side_map("{side}{bone}", {"Shoulder": "Shoulder", "Arm": "UpperArm", "UpArm": "UpperArm",
                                          "ForeArm": "LowerArm", "Hand": "Hand", "UpLeg": "UpperLeg",
                                          "Leg": "LowerLeg", "Foot": "Foot", "ToeBase": "Toes", "Toe": "Toes"})},
}

REQUIRED_BONES = ("Hips", "Spine", "Head", "LeftUpperArm", "LeftLowerArm", "RightUpperArm", "RightLowerArm",
                  "LeftUpperLeg", "LeftLowerLeg", "RightUpperLeg", "RightLowerLeg")


def normalise_name(name: str) -> str:
    name = re.split(r"[:|]", name)[-1]  # namespace prefixes: "mixamorig:Hips", "Char|Hips"
    return re.sub(r"[^a-z0-9]", "", name.lower())


def load_user_map(path: str | Path) -> dict[str, str]:
    """A JSON or TOML table {source joint name: humanoid bone name}."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
        table = tomllib.loads(text) if path.suffix.lower() == ".toml" else json.loads(text)
    except (OSError, ValueError) as exc:
        raise UserError(f"cannot read bone map {path}: {exc}; give a JSON or TOML table of "
                        f"source joint name to humanoid bone name") from None
    if not isinstance(table, dict) or not all(isinstance(v, str) for v in table.values()):
        raise UserError(f"bone map {path} must be a flat table of source joint name to humanoid bone name")
    bad = sorted(set(table.values()) - set(HUMANOID_BONES))
    if bad:
        raise UserError(f"bone map {path} names unknown humanoid bones {bad}; use Unity HumanBodyBones "
                        f"names such as {', '.join(HUMANOID_BONES[:4])}")
    return dict(table)


def match_bones(skeleton: Skeleton, user_map: dict[str, str] | None = None) -> dict[str, int]:
    """Humanoid bone -> source joint index; a user map wins over the built-in maps."""
    by_norm: dict[str, str] = {}
    for table in BUILTIN_MAPS.values():
        for src, dst in table.items():
            by_norm.setdefault(normalise_name(src), dst)
    for src, dst in (user_map or {}).items():
        by_norm[normalise_name(src)] = dst
    matched: dict[str, int] = {}
    for j, name in enumerate(skeleton.names):
        bone = by_norm.get(normalise_name(name))
        if bone is not None and bone not in matched:
            matched[bone] = j
    return matched


@dataclass(frozen=True, eq=False)
class Retarget:
    """The mapping between one source skeleton and the canonical humanoid."""

    source: Skeleton
    bone_source: tuple[int, ...]  # per humanoid bone: source joint index, or -1 if absent
    tpose_world: np.ndarray  # (J_src, 4): source joints' world rotations in the T-pose
    tpose_positions: np.ndarray  # (J_src, 3): source joints' world positions in the T-pose
    humanoid: Skeleton  # canonical bones, T-pose rest, the source's bone lengths
    rest_offsets: np.ndarray  # the source's bone offsets the T-pose was built from
    matched: dict  # humanoid bone -> source joint index
    twists: dict  # limb bone -> quarter-turn twist convention (degrees)

    @classmethod
    def build(cls, source: Skeleton, user_map: dict[str, str] | None = None,
              rest_offsets: np.ndarray | None = None) -> "Retarget":
        matched = match_bones(source, user_map)
        missing = [b for b in REQUIRED_BONES if b not in matched]
        if missing:
            raise UserError(
                f"cannot map skeleton to the humanoid: no joint found for {', '.join(missing)}; "
                f"pass --map FILE with a JSON table such as {{\"{source.names[min(1, len(source) - 1)]}\": \"Hips\"}}")
        offsets = source.offsets if rest_offsets is None else np.asarray(rest_offsets, float)
        return cls._solve(source, matched, offsets, {})

    @classmethod
    def _solve(cls, source: Skeleton, matched: dict, offsets: np.ndarray, twists: dict) -> "Retarget":
        bone_source = tuple(matched.get(b, -1) for b in HUMANOID_BONES)
        tpose_world, tpose_pos = _solve_tpose(source, offsets, matched, twists)
        humanoid = _humanoid_skeleton(source, bone_source, tpose_world, tpose_pos)
        return cls(source, bone_source, tpose_world, tpose_pos, humanoid, offsets, dict(matched), dict(twists))

    def with_twists(self, twists: dict[str, float]) -> "Retarget":
        return self._solve(self.source, self.matched, self.rest_offsets, twists)

    @classmethod
    def for_clip(cls, clip: Clip, user_map: dict[str, str] | None = None) -> "Retarget":
        """Like ``build``, with bone lengths taken from the clip's animated translations
        where it has them (the median, robust to a stray frame), and each limb's twist
        convention read from the motion (``calibrate_twists``)."""
        offsets = None
        if clip.translations is not None:
            offsets = np.median(clip.translations, axis=0)
            offsets[0] = clip.skeleton.offsets[0]
        retarget = cls.build(clip.skeleton, user_map, offsets)
        return retarget.with_twists(calibrate_twists(retarget, clip))

    @property
    def mapped(self) -> dict[str, str]:
        return {b: self.source.names[s] for b, s in zip(HUMANOID_BONES, self.bone_source) if s >= 0}

    @property
    def missing(self) -> list[str]:
        return [b for b, s in zip(HUMANOID_BONES, self.bone_source) if s < 0]

    def to_humanoid(self, clip: Clip) -> Clip:
        """Source motion -> humanoid motion (T-pose-relative local rotations)."""
        world_p, world_r = forward_kinematics(clip)
        T = clip.num_frames
        h_world = np.empty((T, len(HUMANOID_BONES), 4))
        for h, (s, parent) in enumerate(zip(self.bone_source, HUMANOID_PARENTS)):
            if s >= 0:
                h_world[:, h] = rot.multiply(world_r[:, s], rot.inverse(self.tpose_world[s]))
            else:  # a bone the source lacks keeps identity local rotation
                h_world[:, h] = h_world[:, parent]
        local = world_to_local(h_world, HUMANOID_PARENTS)
        hips = self.bone_source[0]
        return Clip(self.humanoid, rot.canonical_hemisphere(local), world_p[:, hips].copy(), clip.fps)

    def to_source(self, motion: Clip, template: Clip | None = None) -> Clip:
        """Humanoid motion -> the source rig. Joints the humanoid does not drive take
        their local rotation and translation from ``template`` (e.g. the clip that was
        restyled) when given, else from the T-pose."""
        T = motion.num_frames
        src = self.source
        h_world = local_to_world(motion.rotations, HUMANOID_PARENTS)
        source_of = {s: h for h, s in enumerate(self.bone_source) if s >= 0}
        if template is not None and template.num_frames != T:
            raise ValueError("template clip must have as many frames as the humanoid motion")
        world = np.empty((T, len(src), 4))
        for j, p in enumerate(src.parents):
            if j in source_of:
                world[:, j] = rot.multiply(h_world[:, source_of[j]], self.tpose_world[j])
            else:
                local = template.rotations[:, j] if template is not None else (
                    self.tpose_world[j] if p < 0 else rot.multiply(rot.inverse(self.tpose_world[p]), self.tpose_world[j]))
                world[:, j] = local if p < 0 else rot.multiply(world[:, p], local)
        local = world_to_local(world, src.parents)
        translations = (template.local_translations() if template is not None
                        else np.broadcast_to(src.offsets, (T, len(src), 3)).copy())
        translations = self._place_hips(translations, world, motion.root_positions)
        has_tr = template is not None and template.translations is not None
        return Clip(src, rot.canonical_hemisphere(local), translations[:, 0].copy(), motion.fps,
                    translations if has_tr else None)

    def _place_hips(self, translations: np.ndarray, world: np.ndarray, hips_world: np.ndarray) -> np.ndarray:
        """Set the local translation of the source's hips joint so its world position is
        ``hips_world``, given the (unchanged) joints above it."""
        chain, j = [], self.bone_source[0]
        while j >= 0:
            chain.append(j)
            j = self.source.parents[j]
        chain.reverse()
        pos = translations[:, chain[0]].copy()
        for parent, child in zip(chain, chain[1:]):
            if child == chain[-1]:
                break
            pos = pos + rot.apply(world[:, parent], translations[:, child])
        if len(chain) == 1:
            translations[:, chain[0]] = hips_world
        else:
            parent = chain[-2]
            translations[:, chain[-1]] = rot.apply(rot.inverse(world[:, parent]), hips_world - pos)
        return translations


def local_to_world(local: np.ndarray, parents: tuple[int, ...]) -> np.ndarray:
    world = np.empty_like(local)
    for j, p in enumerate(parents):
        world[:, j] = local[:, j] if p < 0 else rot.multiply(world[:, p], local[:, j])
    return world


def world_to_local(world: np.ndarray, parents: tuple[int, ...]) -> np.ndarray:
    local = np.empty_like(world)
    for j, p in enumerate(parents):
        local[:, j] = world[:, j] if p < 0 else rot.multiply(rot.inverse(world[:, p]), world[:, j])
    return local


def _rest_positions(parents: tuple[int, ...], offsets: np.ndarray) -> np.ndarray:
    p = np.zeros((len(parents), 3))
    for j, parent in enumerate(parents):
        if parent >= 0:
            p[j] = p[parent] + offsets[j]
    return p


def _aim_vector(bone: str, j: int, matched: dict[str, int], source: Skeleton, rest: np.ndarray,
                end_sites: dict[int, np.ndarray]) -> np.ndarray | None:
    """Rest-pose vector from joint j along its bone, or None when the bone has no length."""
    for target in _AIM.get(bone, ()):
        if target in matched:
            v = rest[matched[target]] - rest[j]
            if np.linalg.norm(v) > 1e-6:
                return v
    # End bones (head, hands, toes): aim at the mean of their children or End Site.
    tips = [rest[c] - rest[j] for c in source.children(j)]
    if j in end_sites:
        tips.append(end_sites[j])
    if tips:
        v = np.mean(tips, axis=0)
        if np.linalg.norm(v) > 1e-6:
            return v
    return None


def _body_frame(up: np.ndarray, left: np.ndarray) -> np.ndarray:
    """The rotation taking the rest pose's (up, left) body axes onto (+Y, +X)."""
    up = up / np.linalg.norm(up)
    left = left - np.dot(left, up) * up
    left = left / np.linalg.norm(left)
    fwd = np.cross(left, up)
    rest_axes = np.stack([left, up, fwd], axis=1)  # columns: body axes in rest space
    return Rotation.from_matrix(rest_axes.T).as_quat()  # maps rest body axes to world X, Y, Z


_SPINE_CHAIN = ("Spine", "Chest", "UpperChest", "Neck", "Head")
# Limb joints whose twist convention is read from the motion: clavicles and legs stay
# near their T-pose direction in everyday motion, so their twist shows. Arms do not:
# raising or waving an arm turns it by up to a quarter turn for real, so the arm chain
# takes its frame from its (calibrated) clavicle.
CALIBRATED_BONES = tuple(f"{side}{b}" for side in ("Left", "Right")
                         for b in ("Shoulder", "UpperLeg", "LowerLeg", "Foot", "Toes"))


def _lateral_axes(matched: dict[str, int], rest: np.ndarray) -> dict[str, np.ndarray]:
    """Rest-pose "left" axes: the hips' from the legs, the spine's from the shoulders
    (or the upper arms), falling back to the hips' when a rig has neither."""
    hips_left = rest[matched["LeftUpperLeg"]] - rest[matched["RightUpperLeg"]]
    for left, right in (("LeftShoulder", "RightShoulder"), ("LeftUpperArm", "RightUpperArm")):
        if left in matched and right in matched:
            spine_left = rest[matched[left]] - rest[matched[right]]
            if np.linalg.norm(spine_left) > 1e-6:
                break
    else:
        spine_left = hips_left
    return {"Hips": hips_left, **{bone: spine_left for bone in _SPINE_CHAIN}}


def _solve_tpose(source: Skeleton, offsets: np.ndarray, matched: dict[str, int],
                 twists: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """World rotation of every source joint in the canonical T-pose (see module doc).

    The hips and spine joints get a full frame from two rest-pose directions (along the
    bone, and the body's left-right line), because the twist of a rig's spine joints
    about their own axis is a convention of the rig that bone directions cannot reveal
    (the Bandai spine is turned 90 degrees from its hips). Limbs are swung from their
    parent's frame.
    """
    rest = _rest_positions(source.parents, offsets)
    end_sites = {j: np.asarray(o) for j, o in source.end_sites}
    lateral = _lateral_axes(matched, rest)
    bone_of = {j: b for b, j in matched.items()}
    world = np.empty((len(source), 4))
    for j, p in enumerate(source.parents):
        inherited = rot.IDENTITY if p < 0 else world[p]
        bone = bone_of.get(j)
        v = None if bone is None else _aim_vector(bone, j, matched, source, rest, end_sites)
        if bone in lateral and v is not None and np.linalg.norm(np.cross(v, lateral[bone])) > 1e-6:
            world[j] = _body_frame(v, lateral[bone])
        elif v is None:
            world[j] = inherited
        else:
            current = rot.apply(inherited, v)
            world[j] = rot.multiply(rot.swing(current, TPOSE_DIRECTION[bone], FORWARD), inherited)
            if twists.get(bone):
                world[j] = rot.multiply(_twist(bone, twists[bone]), world[j])
    positions = np.zeros((len(source), 3))
    for j, p in enumerate(source.parents):
        positions[j] = offsets[j] if p < 0 else positions[p] + rot.apply(world[p], offsets[j])
    return world, positions


def _twist(bone: str, degrees: float) -> np.ndarray:
    """A turn about the bone's own T-pose direction (it keeps the bone's aim)."""
    axis = np.asarray(TPOSE_DIRECTION[bone]) / np.linalg.norm(TPOSE_DIRECTION[bone])
    return Rotation.from_rotvec(np.radians(degrees) * axis).as_quat()


def mean_twist(local: np.ndarray, bone: str, max_swing_deg: float = 45.0) -> float | None:
    """Circular mean (degrees) of the twist of local rotations (T, 4) about the bone's
    T-pose direction (swing-twist decomposition L = swing * twist), or None when the
    motion does not show it reliably.

    Twist is only well defined while the swing is small: an arm hanging 80 degrees
    from the T-pose splits into swing and twist differently with every small change.
    So only frames with the bone within ``max_swing_deg`` of its T-pose direction
    count, and the answer must be concentrated and near a quarter turn.
    """
    axis = np.asarray(TPOSE_DIRECTION[bone]) / np.linalg.norm(TPOSE_DIRECTION[bone])
    swing_cos = np.sum(rot.apply(local, axis) * axis, axis=-1)
    near = local[swing_cos > np.cos(np.radians(max_swing_deg))]
    if len(near) < max(5, 0.5 * len(local)):
        return None
    phasors = np.exp(1j * 2.0 * np.arctan2(near[:, :3] @ axis, near[:, 3]))
    mean = np.mean(phasors)
    degrees = float(np.degrees(np.angle(mean)))
    off_quarter = abs(degrees - 90.0 * round(degrees / 90.0))
    if abs(mean) < 0.5 or off_quarter > 30.0:
        return None
    return degrees


def calibrate_twists(retarget: "Retarget", clip: Clip, max_frames: int = 240) -> dict[str, float]:
    """Each limb joint's twist convention, in quarter turns, read from the motion.

    A rig may turn a limb joint's frame about the bone by a multiple of 90 degrees
    relative to its parent (the Bandai rig turns both clavicles by -90 and the right
    thigh by 180); neither the rest pose nor bone directions show it, but the motion
    does: the limb's mean twist about its own axis sits near that multiple instead of
    near zero. Parents are calibrated first (CALIBRATED_BONES is in hierarchy order per
    side), since a parent's turn changes its children's twist. Rounding to quarter
    turns keeps ordinary motion from moving the reference; the result for every Bandai
    clip sampled is the same (both clavicles -90, right thigh 180).
    """
    step = max(1, clip.num_frames // max_frames)
    sample = clip.replace(
        rotations=clip.rotations[::step], root_positions=clip.root_positions[::step],
        translations=None if clip.translations is None else clip.translations[::step])
    twists: dict[str, float] = {}
    current = retarget
    for bone in CALIBRATED_BONES:
        h = HUMANOID_BONES.index(bone)
        if current.bone_source[h] < 0:
            continue
        twist = mean_twist(current.to_humanoid(sample).rotations[:, h], bone)
        quarter = 0 if twist is None else round(twist / 90.0) % 4
        if quarter:
            twists[bone] = 90.0 * quarter
            current = current.with_twists(twists)
    return twists


def _humanoid_skeleton(source: Skeleton, bone_source: tuple[int, ...], tpose_world: np.ndarray,
                       tpose_pos: np.ndarray) -> Skeleton:
    """Canonical bones at their T-pose positions; a missing bone sits on its parent."""
    pos = np.zeros((len(HUMANOID_BONES), 3))
    for h, (s, parent) in enumerate(zip(bone_source, HUMANOID_PARENTS)):
        pos[h] = tpose_pos[s] if s >= 0 else pos[parent]
    offsets = np.array([pos[h] - pos[p] if p >= 0 else np.zeros(3) for h, p in enumerate(HUMANOID_PARENTS)])
    end_sites = []
    source_end = dict(source.end_sites)
    for h, bone in enumerate(HUMANOID_BONES):
        s = bone_source[h]
        if bone in ("Head", "LeftHand", "RightHand", "LeftToes", "RightToes") and s >= 0:
            end_sites.append((h, tuple(rot.apply(tpose_world[s], np.asarray(source_end.get(s, (0.0, 0.0, 0.0)))))))
    return Skeleton(HUMANOID_BONES, HUMANOID_PARENTS, offsets, end_sites=tuple(end_sites))


def humanoid_skeleton_default() -> Skeleton:
    """A humanoid of typical adult proportions (cm), for sources that carry no skeleton
    of their own (tracker solvers, VMC receivers)."""
    dirs = {b: np.asarray(TPOSE_DIRECTION[b]) for b in HUMANOID_BONES}
    lengths = {"Spine": 10, "Chest": 12, "UpperChest": 12, "Neck": 14, "Head": 10,
               "LeftShoulder": 0, "LeftUpperArm": 17, "LeftLowerArm": 28, "LeftHand": 25,
               "LeftUpperLeg": 0, "LeftLowerLeg": 42, "LeftFoot": 40, "LeftToes": 14}
    offsets = np.zeros((len(HUMANOID_BONES), 3))
    for h, (bone, parent) in enumerate(HUMANOID_HIERARCHY):
        if parent is None:
            continue
        key = bone.replace("Right", "Left")
        offsets[h] = dirs[parent] * lengths.get(key, 0)
        if bone.endswith("Shoulder"):
            offsets[h] = np.array([2.0 if bone.startswith("Left") else -2.0, 9.0, 0.0])
        if bone.endswith("UpperLeg"):
            offsets[h] = np.array([9.0 if bone.startswith("Left") else -9.0, -6.0, 0.0])
    return Skeleton(HUMANOID_BONES, HUMANOID_PARENTS, offsets)
