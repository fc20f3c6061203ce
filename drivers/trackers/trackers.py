"""Shared tracker vocabulary: roles, samples, where trackers are strapped, frame assembly.

A tracker is a rigid body reported as a position and an orientation in the internal space
of ``stylecast.motion.rotations`` (right-handed, Y up, performer facing +Z, left is +X,
centimetres, quaternions x, y, z, w). Serial trackers (``serial_trackers``), VMC tracker
messages (``vmc_parse``) and the emulator (``emulator``) all produce ``TrackerSample``; the
solver (``solver``) consumes them.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np


class TrackerRole(enum.IntEnum):
    """Where a tracker is worn. The integer values are the wire codes of the serial framing
    (docs/SERIAL_FRAMING.md): never renumber them."""

    HMD = 0  # the headset (or a head tracker)
    LEFT_HAND = 1  # controllers
    RIGHT_HAND = 2
    WAIST = 3
    LEFT_ELBOW = 4
    RIGHT_ELBOW = 5
    LEFT_KNEE = 6
    RIGHT_KNEE = 7
    LEFT_FOOT = 8
    RIGHT_FOOT = 9

    @property
    def bone(self) -> str:
        """The humanoid bone the tracker is strapped to (it moves rigidly with it)."""
        return ROLE_BONES[self]

    @property
    def serial(self) -> str:
        """The tracker serial string the emulator sends over VMC (/VMC/Ext/*/Pos)."""
        return f"stylecast-{self.name.lower().replace('_', '-')}"

    @property
    def vmc_kind(self) -> str:
        """"Hmd", "Con" or "Tra": which VMC tracker address carries this role."""
        if self is TrackerRole.HMD:
            return "Hmd"
        if self in (TrackerRole.LEFT_HAND, TrackerRole.RIGHT_HAND):
            return "Con"
        return "Tra"

    @classmethod
    def parse(cls, text: str) -> "TrackerRole | None":
        """A role from its name ("LEFT_FOOT", "left-foot", "head", "stylecast-waist"),
        or None. Lets VMC receivers map tracker serials to roles."""
        key = text.strip().lower()
        if key.startswith("stylecast-"):
            key = key[len("stylecast-"):]
        key = key.replace("-", "_").replace(" ", "_")
        key = {"head": "hmd", "hip": "waist", "hips": "waist", "pelvis": "waist"}.get(key, key)
        return cls.__members__.get(key.upper())


ROLE_BONES: dict[TrackerRole, str] = {
    TrackerRole.HMD: "Head",
    TrackerRole.LEFT_HAND: "LeftHand",
    TrackerRole.RIGHT_HAND: "RightHand",
    TrackerRole.WAIST: "Hips",
    # Elbow and knee trackers sit on the upper segment just above the joint, where straps
    # hold best (upper arm above the elbow, thigh above the knee).
    TrackerRole.LEFT_ELBOW: "LeftUpperArm",
    TrackerRole.RIGHT_ELBOW: "RightUpperArm",
    TrackerRole.LEFT_KNEE: "LeftUpperLeg",
    TrackerRole.RIGHT_KNEE: "RightUpperLeg",
    TrackerRole.LEFT_FOOT: "LeftFoot",
    TrackerRole.RIGHT_FOOT: "RightFoot",
}

# Where a tracker sits on its bone, in the bone's T-pose frame (world-aligned: +X left,
# +Y up, +Z forward): (fraction of the way along the bone towards its child joint,
# perpendicular offset in cm, rotation of the tracker relative to the bone as a rotation
# vector in degrees). The emulator straps trackers like this; T-pose calibration assumes
# it (known-pose calibration measures the real offsets instead).
NOMINAL_MOUNTS: dict[TrackerRole, tuple[float, tuple[float, float, float], tuple[float, float, float]]] = {
    TrackerRole.HMD: (0.0, (0.0, 9.0, 11.0), (0.0, 0.0, 0.0)),  # in front of the eyes
    TrackerRole.LEFT_HAND: (0.0, (7.0, -3.0, 0.0), (0.0, -90.0, 0.0)),  # grip in the palm
    TrackerRole.RIGHT_HAND: (0.0, (-7.0, -3.0, 0.0), (0.0, 90.0, 0.0)),
    TrackerRole.WAIST: (0.0, (0.0, 2.0, -13.0), (0.0, 180.0, 0.0)),  # belt, small of the back
    TrackerRole.LEFT_ELBOW: (0.8, (0.0, 0.0, -5.0), (90.0, 0.0, 0.0)),  # back of the upper arm
    TrackerRole.RIGHT_ELBOW: (0.8, (0.0, 0.0, -5.0), (90.0, 0.0, 0.0)),
    TrackerRole.LEFT_KNEE: (0.8, (0.0, 0.0, 7.0), (0.0, 0.0, 0.0)),  # front of the thigh
    TrackerRole.RIGHT_KNEE: (0.8, (0.0, 0.0, 7.0), (0.0, 0.0, 0.0)),
    TrackerRole.LEFT_FOOT: (0.5, (0.0, 4.0, 0.0), (-30.0, 0.0, 0.0)),  # on the instep
    TrackerRole.RIGHT_FOOT: (0.5, (0.0, 4.0, 0.0), (-30.0, 0.0, 0.0)),
}

ALL_ROLES: tuple[TrackerRole, ...] = tuple(TrackerRole)
TEN_POINT: tuple[TrackerRole, ...] = ALL_ROLES
SIX_POINT: tuple[TrackerRole, ...] = (
    TrackerRole.HMD, TrackerRole.LEFT_HAND, TrackerRole.RIGHT_HAND, TrackerRole.WAIST,
    TrackerRole.LEFT_FOOT, TrackerRole.RIGHT_FOOT,
)


def roles_for_points(points: int) -> tuple[TrackerRole, ...]:
    if points == 10:
        return TEN_POINT
    if points == 6:
        return SIX_POINT
    from stylecast.motion.errors import UserError

    raise UserError(f"unsupported tracker count {points}; use 10 (full VIVE set) or 6 (head, hands, waist, feet)")


class TrackerStatus(enum.IntFlag):
    """Status bits (wire byte of the serial framing)."""

    NONE = 0
    TRACKING_VALID = 0x01  # the pose is current; clear while the tracker is occluded/lost
    POSITION_ESTIMATED = 0x02  # IMU dead-reckoning, no optical fix (pose still usable)
    BATTERY_LOW = 0x04
    BUTTON = 0x08  # any button / trigger pressed (controllers)


@dataclass(frozen=True, eq=False)
class TrackerSample:
    """One pose report of one tracker."""

    tracker_id: int  # device id, unique per performer (0..65535 on the serial wire)
    role: TrackerRole
    timestamp: float  # seconds on the device's clock (µs resolution on the wire)
    position: np.ndarray  # (3,) centimetres, internal space
    orientation: np.ndarray  # (4,) quaternion x, y, z, w, internal space
    status: TrackerStatus = TrackerStatus.TRACKING_VALID

    @property
    def valid(self) -> bool:
        return bool(self.status & TrackerStatus.TRACKING_VALID)

    def __eq__(self, other: object) -> bool:  # handy in tests: equal up to float32 storage
        return (isinstance(other, TrackerSample) and self.tracker_id == other.tracker_id
                and self.role == other.role and self.status == other.status
                and abs(self.timestamp - other.timestamp) < 1e-6
                and np.allclose(self.position, other.position, atol=1e-3)
                and np.allclose(self.orientation, other.orientation, atol=1e-6))

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        p = ", ".join(f"{v:.2f}" for v in self.position)
        q = ", ".join(f"{v:.3f}" for v in self.orientation)
        return (f"TrackerSample(id={self.tracker_id}, {self.role.name}, t={self.timestamp:.6f}, "
                f"p=({p}), q=({q}), status={int(self.status):#04x})")


@dataclass
class TrackerPoses:
    """The latest pose of every role at one instant, as arrays the solver vectorises over:
    ``positions`` (R, 3), ``orientations`` (R, 4), ``valid`` (R,) indexed by ``TrackerRole``."""

    timestamp: float
    positions: np.ndarray = field(default_factory=lambda: np.zeros((len(ALL_ROLES), 3)))
    orientations: np.ndarray = field(default_factory=lambda: np.tile([0.0, 0.0, 0.0, 1.0], (len(ALL_ROLES), 1)))
    valid: np.ndarray = field(default_factory=lambda: np.zeros(len(ALL_ROLES), bool))

    @classmethod
    def from_samples(cls, samples: list[TrackerSample], timestamp: float | None = None) -> "TrackerPoses":
        poses = cls(timestamp if timestamp is not None else max((s.timestamp for s in samples), default=0.0))
        for s in samples:
            poses.positions[s.role] = s.position
            poses.orientations[s.role] = s.orientation
            poses.valid[s.role] = s.valid
        return poses


class FrameAssembler:
    """Groups a stream of samples into instants: trackers that share a timestamp form one
    frame, emitted when a later timestamp arrives (or on ``flush``). A sample older than the
    frame being filled is late and dropped (counted): the solver never goes back in time."""

    def __init__(self) -> None:
        self._pending: dict[TrackerRole, TrackerSample] = {}
        self._time: float | None = None
        self.late_samples = 0

    def feed(self, samples: list[TrackerSample]) -> list[TrackerPoses]:
        out = []
        for s in samples:
            if self._time is not None and s.timestamp < self._time - 1e-7:
                self.late_samples += 1
                continue
            if self._time is not None and s.timestamp > self._time + 1e-7:
                out.append(self.flush())
            self._time = s.timestamp
            self._pending[s.role] = s
        return [f for f in out if f is not None]

    def flush(self) -> TrackerPoses | None:
        if not self._pending:
            return None
        frame = TrackerPoses.from_samples(list(self._pending.values()), self._time)
        self._pending = {}
        return frame


# The child joint each mounted bone points at (for NOMINAL_MOUNTS' "fraction along").
MOUNT_CHILD = {"LeftUpperArm": "LeftLowerArm", "RightUpperArm": "RightLowerArm",
                "LeftUpperLeg": "LeftLowerLeg", "RightUpperLeg": "RightLowerLeg",
                "LeftFoot": "LeftToes", "RightFoot": "RightToes"}


def nominal_mount(role: TrackerRole, skeleton) -> tuple[np.ndarray, np.ndarray]:
    """(position (3,) cm, rotation (4,) xyzw) of a tracker in its bone's frame for a humanoid
    ``skeleton`` (``motion.humanoid`` bone names), per NOMINAL_MOUNTS."""
    from scipy.spatial.transform import Rotation

    frac, perp, rotvec = NOMINAL_MOUNTS[role]
    pos = np.asarray(perp, float).copy()
    child = MOUNT_CHILD.get(role.bone)
    if child is not None and frac:
        pos += frac * np.asarray(skeleton.offsets[skeleton.index(child)], float)
    return pos, Rotation.from_rotvec(np.radians(rotvec)).as_quat()


def parse_role_map(url_text: str, raw: str) -> dict[str, "TrackerRole"]:
    """``roles=LHR-1A2B3C:left-foot,LHR-4D5E6F:waist`` -> {serial: role}: which body part
    each tracker (by its serial) is strapped to. One sentence on a bad entry."""
    from stylecast.motion.errors import UserError

    out: dict[str, TrackerRole] = {}
    for entry in filter(None, (e.strip() for e in raw.split(","))):
        serial, sep, name = entry.rpartition(":")
        role = TrackerRole.parse(name) if sep and serial else None
        if role is None:
            known = ", ".join(r.name.lower().replace("_", "-") for r in TrackerRole)
            raise UserError(f"{url_text}: roles entry {entry!r} must be SERIAL:ROLE with ROLE one of {known}")
        if serial in out:
            raise UserError(f"{url_text}: tracker {serial} is given two roles; give each serial once")
        out[serial] = role
    return out


def vmc_tracker_role(kind: str, serial: str, role_map: dict | None = None) -> "TrackerRole | None":
    """The body role of a VMC tracker: the user's map first, then a serial that names a
    role (the emulator's "stylecast-left-foot", or "waist"), then the headset by its
    address (/VMC/Ext/Hmd/Pos). Controllers and trackers with a bare serial need the map."""
    if role_map and serial in role_map:
        return role_map[serial]
    role = TrackerRole.parse(serial)
    if role is None and kind == "hmd":
        role = TrackerRole.HMD
    return role


def samples_from_vmc(trackers, timestamp: float, role_map: dict | None = None) -> list[TrackerSample]:
    """VMC tracker messages (``vmc_parse.TrackerSample``: kind, serial, position, rotation)
    -> TrackerSamples, the role from ``vmc_tracker_role``. Trackers with no role are left
    out; the tracker id is the role code. When a sender sends a tracker both avatar-scaled
    and raw (/Local), the avatar-scaled one is used."""
    chosen: dict[TrackerRole, object] = {}
    for t in trackers:
        role = vmc_tracker_role(t.kind, str(t.serial), role_map)
        if role is None or (role in chosen and not getattr(chosen[role], "local", False)):
            continue
        chosen[role] = t
    return [TrackerSample(int(role), role, float(timestamp), np.asarray(t.position, float), np.asarray(t.rotation, float))
            for role, t in chosen.items()]


class VmcTrackerFeed:
    """Tracker samples from a ``vmc_in.VmcReceiver`` (trackers sent over VMC by an
    assistant, or by ``stylecast emulate --to vmc://``), in the shape ``solver.
    SolvedTrackerSource`` pulls from: ``poll() -> list[TrackerSample]``. A frame's
    samples carry the sender's /VMC/Ext/T time when it sent one (so they group into one
    instant), else the receive time."""

    def __init__(self, receiver):
        self.receiver = receiver

    def poll(self) -> list[TrackerSample]:
        out: list[TrackerSample] = []
        for frame in self.receiver.poll(0.0):
            if frame.trackers:
                t = frame.sender_time if frame.sender_time is not None else frame.timestamp
                out += samples_from_vmc(frame.trackers, t)
        return out

    def close(self) -> None:
        self.receiver.close()
