"""The tracker emulator, `stylecast emulate`, and the serial / VMC paths end to end."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from stylecast.cli import main
from stylecast.drivers.cli import open_tracker_sink as open_sink
from stylecast.drivers.trackers.emulator import Emulator, emulate_trackers
from stylecast.drivers.serial.serial_trackers import PACKET_LEN, FrameDecoder, SerialTrackerSink, encode_packets
from stylecast.drivers.trackers.solver import TrackerSolver, calibrate_known_pose
from stylecast.drivers.trackers.trackers import (SIX_POINT, TEN_POINT, FrameAssembler, TrackerPoses, TrackerRole,
                                        nominal_mount, samples_from_vmc)
from stylecast.motion import forward_kinematics
from stylecast.motion import rotations as rot
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import HUMANOID_BONES

from .test_serial_trackers import FakeClock, _raw_master, _read_all
from .test_solver import BONE, body_motion, joint_errors


def test_trackers_sit_rigidly_on_their_bones():
    motion = body_motion(frames=50)
    rec = emulate_trackers(motion, 10)
    pos, wrot = forward_kinematics(motion)
    assert rec.roles == TEN_POINT and rec.valid.all()
    for role in TEN_POINT:
        mp, mq = nominal_mount(role, motion.skeleton)
        b = BONE[role.bone]
        assert np.allclose(rec.positions[:, role], pos[:, b] + rot.apply(wrot[:, b], mp))
        assert np.allclose(np.abs(np.sum(rec.orientations[:, role] * rot.multiply(wrot[:, b], mq), -1)), 1)
    head = pos[:, BONE["Head"]]
    hmd_local = rot.apply(rot.inverse(wrot[:, BONE["Head"]]), rec.positions[:, TrackerRole.HMD] - head)
    assert np.all(hmd_local[:, 2] > 5)  # the headset is in front of the head
    assert np.allclose(rec.timestamps[:3], [0, 1 / 60, 2 / 60])


def test_six_points_report_only_their_trackers():
    rec = emulate_trackers(body_motion(frames=20), 6)
    assert rec.roles == SIX_POINT
    assert rec.valid[:, list(SIX_POINT)].all() and not rec.valid[:, TrackerRole.LEFT_ELBOW].any()
    assert len(rec.samples(0)) == 6


def test_noise_and_seed():
    motion = body_motion(frames=400)
    clean = emulate_trackers(motion, 10)
    a = emulate_trackers(motion, 10, noise_mm=5, seed=3)
    b = emulate_trackers(motion, 10, noise_mm=5, seed=3)
    c = emulate_trackers(motion, 10, noise_mm=5, seed=4)
    d = (a.positions - clean.positions).reshape(-1)
    assert np.std(d) == pytest.approx(0.5, rel=0.05)  # 5 mm = 0.5 cm per axis
    assert np.array_equal(a.positions, b.positions) and not np.array_equal(a.positions, c.positions)


def test_dropouts_come_in_bursts_and_repeat_the_last_pose():
    rec = emulate_trackers(body_motion(frames=2000), 10, drop=0.1, seed=1)
    lost = ~rec.valid[:, list(TEN_POINT)]
    assert lost.mean() == pytest.approx(0.1, abs=0.03)
    starts = (lost[1:] & ~lost[:-1]).sum()
    assert lost[1:].sum() / max(starts, 1) > 3  # mean burst length of several frames
    t, r = np.argwhere(lost[1:] & ~lost[:-1])[0]
    t += 1
    assert np.array_equal(rec.positions[t, r], rec.positions[t - 1, r])
    assert not rec.samples(t)[r].valid


@pytest.mark.parametrize("kwargs", [dict(noise_mm=-1), dict(drop=1.0), dict(speed=0)])
def test_bad_options_are_user_errors(kwargs):
    with pytest.raises(UserError):
        emulate_trackers(body_motion(frames=5), 10, **kwargs)
    with pytest.raises(UserError):
        emulate_trackers(body_motion(frames=5), 7)


class ListSink:
    def __init__(self):
        self.frames = []

    def send(self, samples):
        self.frames.append(samples)


def test_emulator_paces_on_the_injected_clock():
    rec = emulate_trackers(body_motion(frames=120), 6, speed=2.0)
    clock = FakeClock(50.0)
    sink = ListSink()
    sent = Emulator(rec, clock).run(sink)
    assert sent == 120 and len(sink.frames) == 120
    assert clock.t - 50.0 == pytest.approx(119 / 120)  # 120 frames of 60 fps at double speed
    sink = ListSink()
    Emulator(rec, FakeClock()).run(sink, loop=True, max_frames=300)
    assert len(sink.frames) == 300
    ts = [f[0].timestamp for f in sink.frames]
    assert np.all(np.diff(ts) > 0)  # looping keeps time running forwards


def test_open_sink_refuses_bad_outputs():
    with pytest.raises(UserError):
        open_sink("ttyUSB0")
    with pytest.raises(UserError):
        open_sink("vmc://127.0.0.1")  # no port


# ----------------------------------------------------------------------------- the CLI

@pytest.fixture()
def bvh_file(tmp_path):
    from stylecast.motion.bvh import write_bvh

    path = tmp_path / "walk.bvh"
    write_bvh(body_motion(frames=90, fps=30.0), path)
    return path


def test_cli_emulate_to_a_real_pty(bvh_file):
    master, slave = os.openpty()
    try:
        _raw_master(master)
        code = main(["emulate", "--bvh", str(bvh_file), "--to", f"serial://{os.ttyname(slave)}?baud=921600",
                     "--points", "6", "--speed", "30", "--frames", "40", "--noise", "1"])
        assert code == 0
        data = _read_all(master, time.monotonic() + 5, 40 * 6 * PACKET_LEN)
        got = FrameDecoder().feed(data)
        assert len(got) == 240 and {s.role for s in got} == set(SIX_POINT)
    finally:
        os.close(master)
        os.close(slave)


@pytest.mark.parametrize("argv, needle", [
    (["--to", "nonsense"], "--to"),
    (["--to", "serial:///dev/ttyUSB0?parity=E"], "baud"),
    (["--to", "loop://", "--drop", "1.5"], "--drop"),
    (["--to", "loop://", "--speed", "0"], "--speed"),
    (["--to", "serial:///dev/no-such-tty"], "cannot open serial output"),
    (["--to", "loop://", "--rate", "0"], "--rate"),
])
def test_cli_errors_are_one_sentence(bvh_file, capsys, argv, needle):
    assert main(["emulate", "--bvh", str(bvh_file), *argv, "--frames", "1"]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err


def test_cli_missing_file(tmp_path, capsys):
    assert main(["emulate", "--bvh", str(tmp_path / "nope.bvh"), "--to", "loop://"]) == 2
    assert "does not exist" in capsys.readouterr().err


# ----------------------------------------------------------------------------- end to end

def _calibrated_solver(motion, rec, n=60):
    cal = calibrate_known_pose(rec.arrays(0, n), motion.slice(0, n), rec.roles)
    return TrackerSolver(cal)


def test_emulator_to_serial_driver_to_solver_over_a_pty():
    """emulator -> SerialTrackerSink on the pty master -> the daemon's serial:// source on
    the slave path (pyserial) -> T-pose calibration -> solver -> PoseFrames."""
    from stylecast.drivers.sources import open_source

    scale = 1.05
    motion = body_motion(frames=150, seed=2, scale=scale)
    tpose = motion.replace(rotations=np.tile(rot.IDENTITY, (70, len(HUMANOID_BONES), 1)),
                           root_positions=np.tile([0.0, 95.0 * scale, 0.0], (70, 1)))
    rec = emulate_trackers(motion.replace(rotations=np.concatenate([tpose.rotations, motion.rotations]),
                                          root_positions=np.concatenate([tpose.root_positions,
                                                                         motion.root_positions])), 10)
    master, slave = os.openpty()
    try:
        _raw_master(master)
        source = open_source(f"serial://{os.ttyname(slave)}?baud=921600&points=10&calibrate=1", "perf")

        class Fd:  # the pty master as a port: SerialTrackerSink writes to its file descriptor
            def fileno(self):
                return master

            def close(self):
                pass

        sink = SerialTrackerSink(port=Fd())
        frames, now = [], 0.0
        for i in range(len(rec)):
            sink.send(rec.samples(i))
            sink.flush()
            now += 1 / 60
            time.sleep(0.0005)
            frames += source.poll(now)
        for _ in range(100):
            now += 0.05
            frames += source.poll(now)
            time.sleep(0.001)
        counters = source.counters()
        assert counters["calibrated"] and counters["packets"] == len(rec) * 10 and not counters["bad_frames"]
        assert source.skeleton is not None
        # 70 T-pose frames: the first second calibrates, the rest are solved.
        assert len(frames) == len(rec) - 61
        tail = len(motion.rotations) - 60
        solved = frames[-tail:]
        assert all(f.performer == "perf" for f in solved)
        root = np.stack([f.root_position for f in solved])
        local = np.stack([f.rotations for f in solved])

        class Cal:
            skeleton = source.skeleton

        err = joint_errors(Cal, root, local, motion.slice(60, motion.num_frames))
        assert err.mean() < 1.5 and np.percentile(err, 95) < 4.0
        assert np.diff([f.timestamp for f in solved]) == pytest.approx(1 / 60, abs=2e-6)  # µs on the wire
        source.close()
    finally:
        os.close(master)
        os.close(slave)


def test_corrupted_line_still_solves():
    """5 % of the bytes corrupted between emulator and solver: no crash, every intact
    packet decoded, bad ones counted, the solver holds what it loses."""
    motion = body_motion(frames=240, seed=3)
    rec = emulate_trackers(motion, 10)
    solver = _calibrated_solver(motion, rec)
    data = np.frombuffer(b"".join(encode_packets(rec.samples(i)) for i in range(60, len(rec))), np.uint8).copy()
    rng = np.random.default_rng(0)
    hit = rng.random(len(data)) < 0.05
    data[hit] ^= rng.integers(1, 256, hit.sum()).astype(np.uint8)
    ok = [not hit[k * PACKET_LEN:(k + 1) * PACKET_LEN].any() for k in range(len(data) // PACKET_LEN)]
    intact = int(sum(ok))  # 0.95 ** 48: fewer than one packet in ten survives
    instants = len({k // 10 for k in range(len(ok)) if ok[k]})
    dec, asm = FrameDecoder(), FrameAssembler()
    poses = []
    for k in range(0, len(data), 97):
        poses += asm.feed(dec.feed(data[k:k + 97].tobytes()))
    poses.append(asm.flush())
    assert dec.frames == intact and dec.bad_frames["crc"] > 0
    out = [solver.solve(p) for p in poses]
    assert all(np.isfinite(f.rotations).all() and np.isfinite(f.root_position).all() for f in out)
    assert len(out) == instants  # an instant is lost only if all ten of its packets are
    assert sum(p.valid.sum() for p in poses) == intact


def test_emulator_to_vmc_receiver_over_loopback():
    from stylecast.drivers.vmc.vmc_in import VmcReceiver

    motion = body_motion(frames=60)
    rec = emulate_trackers(motion, 10)
    with VmcReceiver("127.0.0.1", 0) as receiver:
        host, port = receiver.address
        sink = open_sink(f"vmc://{host}:{port}")
        Emulator(rec, FakeClock()).run(sink, max_frames=20)
        got = []
        deadline = time.monotonic() + 5
        while len(got) < 20 and time.monotonic() < deadline:
            got += [f for f in receiver.poll(0.05) if f.trackers]
        sink.close()
    assert len(got) == 20
    for i, frame in enumerate(got):
        samples = samples_from_vmc(frame.trackers, frame.timestamp)
        assert {s.role for s in samples} == set(TEN_POINT)
        poses = TrackerPoses.from_samples(samples)
        assert np.allclose(poses.positions, rec.positions[i], atol=1e-3)  # float32 metres
        assert np.allclose(np.abs(np.sum(poses.orientations * rec.orientations[i], -1)), 1, atol=1e-5)


def test_pty_to_daemon_to_vmc_out():
    """The whole live path: emulator -> pty -> the daemon's serial:// source (T-pose
    calibration, solver) -> the daemon (identity restyler) -> VMC out over loopback UDP ->
    a VMC receiver. The hips the receiver sees follow the emulated performer."""
    from stylecast.motion.clock import FakeClock as DaemonClock
    from stylecast.daemon.config import DaemonConfig
    from stylecast.daemon.engine import Daemon
    from stylecast.daemon.restylers import IdentityRestyler
    from stylecast.drivers.sources import open_source
    from stylecast.drivers.vmc.vmc_in import VmcReceiver

    motion = body_motion(frames=130, seed=11)
    tpose = np.tile(rot.IDENTITY, (70, len(HUMANOID_BONES), 1))
    whole = motion.replace(rotations=np.concatenate([tpose, motion.rotations]),
                           root_positions=np.concatenate([np.tile(motion.root_positions[:1], (70, 1)),
                                                          motion.root_positions]))
    rec = emulate_trackers(whole, 10, noise_mm=1, seed=5)
    master, slave = os.openpty()
    receiver = VmcReceiver("127.0.0.1", 0)
    daemon = None
    try:
        _raw_master(master)
        host, port = receiver.address
        source = open_source(f"serial://{os.ttyname(slave)}?points=10&calibrate=1", "p0")
        cfg = DaemonConfig(hop=5, control="off", out=[f"vmc://{host}:{port}"])
        daemon = Daemon(cfg, [source], IdentityRestyler(), DaemonClock(), log_status=False)
        daemon.start()
        frames = []
        for i in range(len(rec) + 40):
            if i < len(rec):
                os.write(master, encode_packets(rec.samples(i)))
                time.sleep(0.0005)
            daemon.step()
            daemon.clock.advance(1 / 60)
            frames += [f for f in receiver.poll(0.0) if f.pose is not None]
        for _ in range(20):
            frames += [f for f in receiver.poll(0.02) if f.pose is not None]
        assert source.counters()["calibrated"] and source.counters()["frames_solved"] >= len(rec) - 62
        hips = np.stack([f.pose.root_position for f in frames])
        assert len(frames) > 100 and np.isfinite(hips).all()
        # The performer walks 80 cm/s along +Z for 2 s: so must the avatar's hips.
        assert hips[:, 2].max() - hips[:, 2].min() > 100
        assert np.abs(hips[-1, 2] - motion.root_positions[-1, 2]) < 30  # (the daemon adds its delay)
    finally:
        if daemon is not None:
            daemon.close()
        receiver.close()
        os.close(master)
        os.close(slave)


def test_vmc_trackers_to_solver_source():
    """emulate --to vmc:// -> VmcReceiver -> VmcTrackerFeed -> SolvedTrackerSource (T-pose
    calibration) -> 60 Hz humanoid frames that follow the performer."""
    from stylecast.drivers.trackers.solver import SolvedTrackerSource
    from stylecast.drivers.trackers.trackers import VmcTrackerFeed
    from stylecast.drivers.vmc.vmc_in import VmcReceiver

    motion = body_motion(frames=90, seed=13)
    whole = motion.replace(
        rotations=np.concatenate([np.tile(rot.IDENTITY, (65, len(HUMANOID_BONES), 1)), motion.rotations]),
        root_positions=np.concatenate([np.tile(motion.root_positions[:1], (65, 1)), motion.root_positions]))
    rec = emulate_trackers(whole, 6)
    receiver = VmcReceiver("127.0.0.1", 0)
    source = SolvedTrackerSource(VmcTrackerFeed(receiver), "vmc-perf", points=6)
    try:
        sink = open_sink("vmc://%s:%d" % receiver.address)
        frames, now = [], 0.0
        for i in range(len(rec)):
            sink.send(rec.samples(i))
            time.sleep(0.0005)
            now += 1 / 60
            frames += source.poll(now)
        for _ in range(50):
            time.sleep(0.005)
            now += 0.01
            frames += source.poll(now)
        sink.close()
    finally:
        source.close()
    assert source.calibrated and len(frames) >= len(rec) - 62
    root = np.stack([f.root_position for f in frames[-60:]])
    ref = motion.root_positions[-60:]
    assert np.abs(root - ref).max() < 1.0  # float32 metres on the wire, then solved
