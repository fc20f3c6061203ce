"""VRChat OSC trackers out (``vrchat://``), checked by a real loopback receiver."""

from __future__ import annotations

import socket

import numpy as np
import pytest
from pythonosc.osc_bundle import OscBundle
from pythonosc.osc_message import OscMessage
from scipy.spatial.transform import Rotation

from stylecast.drivers.urls import parse_url
from stylecast.drivers.vrchat.vrchat_out import TRACKERS, open_sink
from stylecast.motion import rotations as rot
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default
from stylecast.motion.errors import UserError

BONE = {b: i for i, b in enumerate(HUMANOID_BONES)}


def receive(sock) -> dict[str, tuple]:
    """Every message of one frame, parsed by python-osc (an independent decoder)."""
    got = {}
    sock.settimeout(2.0)
    while True:
        try:
            data, _ = sock.recvfrom(65536)
        except socket.timeout:
            break
        items = list(OscBundle(data)) if OscBundle.dgram_is_bundle(data) else [OscMessage(data)]
        for m in items:
            got[m.address] = tuple(m.params)
        sock.settimeout(0.2)
    return got


@pytest.fixture
def receiver():
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    yield sock
    sock.close()


def send_pose(receiver, rotations, root_cm, url="vrchat://127.0.0.1:{port}?head=1"):
    port = receiver.getsockname()[1]
    skeleton = humanoid_skeleton_default()
    sink = open_sink(parse_url(url.format(port=port)), [("127.0.0.1", port)])
    try:
        sink.send(np.asarray(root_cm, float), rotations, skeleton.offsets, 0.0)
    finally:
        sink.close()
    return receive(receiver), skeleton


def test_trackers_carry_unity_positions_in_metres_and_the_left_stays_left(receiver):
    pose = rot.identity((len(HUMANOID_BONES),))
    # Raise the left arm: in internal space the left arm points +X; turn the upper arm so
    # it points up (+Y) instead.
    pose[BONE["LeftUpperArm"]] = Rotation.from_euler("z", 90, degrees=True).as_quat()
    got, skeleton = send_pose(receiver, pose, [10.0, 95.0, 20.0])
    expected = {f"/tracking/trackers/{i}/{w}" for i in [*TRACKERS, "head"] for w in ("position", "rotation")}
    assert set(got) == expected
    assert all(len(v) == 3 and all(isinstance(x, float) for x in v) for v in got.values())
    hips = np.array(got["/tracking/trackers/1/position"])
    assert np.allclose(hips, [-0.10, 0.95, 0.20], atol=1e-6)  # cm -> m, X mirrored
    left_foot, right_foot = (np.array(got[f"/tracking/trackers/{i}/position"]) for i in ("2", "3"))
    # Unity: the avatar faces +Z and its left is -X. Feet 9 cm either side, 88 cm below the hips.
    assert left_foot[0] == pytest.approx(-0.10 - 0.09, abs=1e-6) and right_foot[0] == pytest.approx(-0.10 + 0.09, abs=1e-6)
    assert left_foot[1] == pytest.approx(0.95 - 0.06 - 0.42 - 0.40, abs=1e-6)
    left_elbow, right_elbow = (np.array(got[f"/tracking/trackers/{i}/position"]) for i in ("7", "8"))
    # The raised left arm: its elbow is above the shoulder, on the avatar's left (-X).
    shoulder_y = 0.95 + (10 + 12 + 12 + 9) / 100
    assert left_elbow[1] == pytest.approx(shoulder_y + 0.28, abs=1e-6) and left_elbow[0] < hips[0]
    assert right_elbow[1] == pytest.approx(shoulder_y, abs=1e-6) and right_elbow[0] > hips[0] + 0.3
    assert np.allclose(got["/tracking/trackers/1/rotation"], 0.0, atol=1e-6)  # T-pose: identity


def test_rotations_are_unity_euler_degrees(receiver):
    pose = rot.identity((len(HUMANOID_BONES),))
    # The performer turns towards their own left (internal +Y by 90 degrees, +Z -> +X) and
    # leans 20 degrees forward. In Unity the left is -X: a yaw of -90 degrees.
    turn = Rotation.from_euler("y", 90, degrees=True) * Rotation.from_euler("x", 20, degrees=True)
    pose[BONE["Hips"]] = turn.as_quat()
    got, _ = send_pose(receiver, pose, [0.0, 95.0, 0.0])
    x, y, z = got["/tracking/trackers/1/rotation"]
    assert (x, y, z) == pytest.approx((20.0, -90.0, 0.0), abs=1e-4)
    # Rebuild the rotation the way Unity does (z, then x, then y about fixed axes) and
    # check that it points the hips' forward (+Z) towards Unity -X.
    q = Rotation.from_euler("zxy", [z, x, y], degrees=True)
    forward = q.apply([0.0, 0.0, 1.0])
    assert forward[0] < -0.9
    # The left foot moved in front of / behind the hips consistently with that turn.
    left_foot = np.array(got["/tracking/trackers/2/position"])
    assert left_foot[2] < -0.05  # the left hip (Unity -X) turned to Unity -Z


def test_head_is_only_sent_when_asked_and_options_are_checked(receiver):
    pose = rot.identity((len(HUMANOID_BONES),))
    got, _ = send_pose(receiver, pose, [0.0, 95.0, 0.0], url="vrchat://127.0.0.1:{port}")
    assert len(got) == 16 and not any("head" in a for a in got)
    with pytest.raises(UserError, match="unknown option hed"):
        open_sink(parse_url("vrchat://127.0.0.1:9000?hed=1"), [("127.0.0.1", 9000)])


def test_the_daemon_sends_trackers_beside_vmc(receiver):
    from stylecast.daemon.config import DaemonConfig
    from stylecast.daemon.engine import Daemon
    from stylecast.daemon.restylers import IdentityRestyler
    from stylecast.drivers.bvh.bvh_replay import ReplaySource
    from stylecast.motion.clock import FakeClock

    from .test_daemon import walk_clip

    port = receiver.getsockname()[1]
    frames = []
    cfg = DaemonConfig(hop=15, control="off", out=[f"vrchat://127.0.0.1:{port}"])
    daemon = Daemon(cfg, [ReplaySource(walk_clip(120), "p0", loop=True)], IdentityRestyler(), FakeClock(),
                    frame_taps=[frames.append], log_status=False)
    try:
        daemon.start()
        for _ in range(16):
            daemon.step()
    finally:
        daemon.close()
    got = receive(receiver)
    assert len(got) == 16 and frames
    hips_cm = frames[-1].root_position
    assert np.allclose(got["/tracking/trackers/1/position"], [-hips_cm[0] / 100, hips_cm[1] / 100, hips_cm[2] / 100],
                       atol=1e-5)
