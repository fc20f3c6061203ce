"""``vrchat://127.0.0.1:9000[?head=1&bundled=1]``: the restyled skeleton as VRChat OSC trackers.

VRChat (docs.vrchat.com, "OSC Trackers") listens on UDP 9000 for up to eight virtual
trackers and drives its calibrated full-body IK with them:

    /tracking/trackers/1..8/position   f x y z   world position, metres
    /tracking/trackers/1..8/rotation   f x y z   world Euler angles, degrees
    /tracking/trackers/head/position, /rotation  (optional, aligns the tracking spaces)

in Unity's space (left-handed, +Y up, 1.0 = 1 m) with Unity's Euler convention (Z, then
X, then Y). The index map is the common one (hip, feet, knees, chest, elbows); VRChat
documents that it accepts "hip, chest, 2x feet, 2x knees, 2x elbows", with the elbow
trackers on the upper arms. Each tracker sits at its joint (knee = the lower leg's
origin, elbow = the lower arm's origin) with that bone's world rotation.

Positions and rotations come from forward kinematics of the frame (the performer's own
bone offsets, root position as sent), then ``motion.unity`` converts them: the only
place an axis is flipped. The head is sent only with ``head=1``: VRChat then uses it to
align our space with the headset's, which suits a performer without an HMD in VRChat.
"""

from __future__ import annotations

import numpy as np

from stylecast.motion.clip import pose_world
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default
from stylecast.motion.unity import position_to_unity, rotation_to_unity, unity_euler_degrees

from stylecast.drivers.vmc.osc_packets import encode_message, pack_datagrams
from stylecast.drivers.urls import EndpointUrl
from stylecast.drivers.vmc.vmc_out import VmcSender

DEFAULT_PORT = 9000
# VRChat tracker index -> humanoid bone whose origin and rotation the tracker follows.
TRACKERS: dict[str, str] = {
    "1": "Hips", "2": "LeftFoot", "3": "RightFoot", "4": "LeftLowerLeg", "5": "RightLowerLeg",
    "6": "Chest", "7": "LeftLowerArm", "8": "RightLowerArm",
}
HEAD = ("head", "Head")
_PARENTS = humanoid_skeleton_default().parents


def tracker_address(index: str, what: str) -> str:
    return f"/tracking/trackers/{index}/{what}"


class VrchatTrackerOut:
    """One performer's trackers to one VRChat (or any receiver of the same addresses)."""

    def __init__(self, targets: list[tuple[str, int]], head: bool = False, bundled: bool = True):
        self.trackers = list(TRACKERS.items()) + ([HEAD] if head else [])
        self._joints = np.array([HUMANOID_BONES.index(bone) for _, bone in self.trackers])
        self.bundled = bundled
        # The UDP fan-out of the VMC sender (non-blocking, loopback-bound, dead receivers
        # counted) carries any OSC datagrams; its VMC encoder is simply not used.
        self.sender = VmcSender(targets, bundled=bundled)
        self.frames_rejected = 0

    def messages(self, root_position: np.ndarray, rotations: np.ndarray, offsets: np.ndarray) -> list[bytes]:
        positions, world = pose_world(_PARENTS, offsets, np.asarray(root_position, np.float64), rotations)
        p = position_to_unity(positions[self._joints])
        e = unity_euler_degrees(rotation_to_unity(world[self._joints]))
        if not (np.isfinite(p).all() and np.isfinite(e).all()):
            raise ValueError("tracker pose is not finite")
        out = []
        for k, (index, _) in enumerate(self.trackers):
            out.append(encode_message(tracker_address(index, "position"), *map(float, p[k])))
            out.append(encode_message(tracker_address(index, "rotation"), *map(float, e[k])))
        return out

    def send(self, root_position: np.ndarray, rotations: np.ndarray, offsets: np.ndarray, time: float) -> None:
        try:
            messages = self.messages(root_position, rotations, offsets)
        except ValueError:
            self.frames_rejected += 1  # never put NaN on the wire
            return
        self.sender.frames_sent += 1
        self.sender.send_datagrams(pack_datagrams(messages, bundled=self.bundled))

    def counters(self) -> dict:
        return {**self.sender.counters(), "frames_rejected": self.frames_rejected}

    def close(self) -> None:
        self.sender.close()


def open_sink(url: EndpointUrl, targets: list[tuple[str, int]], bundled: bool = True, tap=None) -> VrchatTrackerOut:
    """The sink factory registered for ``vrchat://`` (see ``sinks.py``); ``tap`` is a
    VMC-byte hook and does not apply here."""
    opts = url.take({"head": (bool, False), "bundled": (bool, None)})
    return VrchatTrackerOut(targets, head=opts["head"], bundled=bundled if opts["bundled"] is None else opts["bundled"])
