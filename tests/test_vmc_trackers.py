"""VIVE-style trackers over VMC into the daemon's ``vmc://`` source, end to end over real
loopback UDP: ``stylecast emulate --to vmc://`` -> vmc:// source (T-pose calibration,
solver) -> daemon -> VMC out -> a VMC receiver."""

from __future__ import annotations

import time

import numpy as np
import pytest

from stylecast.daemon.clips import bundled_clip
from stylecast.daemon.config import DaemonConfig
from stylecast.daemon.engine import Daemon
from stylecast.daemon.restylers import IdentityRestyler
from stylecast.drivers.bvh.bvh_replay import humanoid_motion
from stylecast.drivers.trackers.emulator import emulate_trackers, with_tpose
from stylecast.drivers.sources import open_source
from stylecast.drivers.vmc.vmc_in import VmcReceiver
from stylecast.drivers.vmc.vmc_out import VmcTrackerSink
from stylecast.motion.bvh import read_bvh
from stylecast.motion.clip import forward_kinematics, pose_world
from stylecast.motion.clock import OUTPUT_FPS, FakeClock
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default
from stylecast.motion.resample import resample

TPOSE_FRAMES = 70  # calibrate=tpose takes the first second; a little more to be safe
PARENTS = humanoid_skeleton_default().parents


def walk(seconds: float = 4.0):
    """The shipped Bandai walk (package data, so no ../shared needed), at 60 fps."""
    motion = resample(humanoid_motion(read_bvh(bundled_clip())), OUTPUT_FPS)
    return motion.slice(0, int(seconds * OUTPUT_FPS))


def performer(seconds: float = 4.0):
    """A taller-than-default performer (x1.06) walking: the humanoid's own bone layout,
    so a T-pose calibration can learn its proportions."""
    from .test_solver import body_motion

    return body_motion(frames=int(seconds * OUTPUT_FPS), fps=OUTPUT_FPS, seed=21, scale=1.06)


def run_trackers_through_daemon(points: int, motion, extra: str = "", drop: float = 0.0):
    rec = emulate_trackers(with_tpose(motion, TPOSE_FRAMES / OUTPUT_FPS), points, drop=drop, seed=4)
    rec.valid[:TPOSE_FRAMES + 5] = rec.valid[:TPOSE_FRAMES + 5] | np.isin(np.arange(10), rec.roles)  # calibrate on all
    out = VmcReceiver("127.0.0.1", 0)
    source = open_source(f"vmc://127.0.0.1:0?points={points}&calibrate=tpose{extra}", "p0")
    sink = VmcTrackerSink("vmc://127.0.0.1:%d" % source.receiver.address[1])
    cfg = DaemonConfig(hop=15, control="off", out=["vmc://127.0.0.1:%d" % out.address[1]])
    daemon = Daemon(cfg, [source], IdentityRestyler(), FakeClock(), log_status=False)
    frames = []
    try:
        daemon.start()
        for i in range(len(rec) + 40):
            if i < len(rec):
                sink.send(rec.samples(i))
                # Let loopback deliver before the tick polls (a loaded machine can take a
                # while): the fake clock must not run ahead of the real packets.
                deadline = time.monotonic() + 2.0
                while source.receiver.delivered <= i and time.monotonic() < deadline:
                    time.sleep(0.0005)
            daemon.step()
            daemon.clock.advance(1 / OUTPUT_FPS)
            frames += [f for f in out.poll(0.0) if f.pose is not None]
        for _ in range(20):
            frames += [f for f in out.poll(0.02) if f.pose is not None]
        counters = source.counters()
    finally:
        daemon.close()
        sink.close()
        out.close()
    return motion, frames, counters, source


def moving(frames):
    """The output frames that show the clip: without the T-pose's tail at the start (the
    calibration took the first second of it) and without the held last pose at the end."""
    hips = np.stack([f.pose.root_position for f in frames])
    still = np.all(np.abs(hips - hips[-1]) < 1e-6, axis=1)
    end = len(frames) - int(np.argmin(still[::-1])) + 1
    return frames[TPOSE_FRAMES - 50:end]


def solved_error(motion, frames) -> tuple[np.ndarray, int]:
    """Per-joint distance (cm) between the FK of the VMC output (with the bone offsets it
    carries) and the clip, at the frame shift (calibration, the daemon's delay) that
    aligns them best."""
    ref, _ = forward_kinematics(motion)
    est = np.stack([pose_world(PARENTS, f.offsets, f.pose.root_position, f.pose.rotations)[0] for f in frames])
    best = None
    for shift in range(-30, 30):
        lo, hi = max(0, -shift), min(len(est), len(ref) - shift)
        if hi - lo < len(ref) - 60:
            continue
        err = np.linalg.norm(est[lo:hi] - ref[lo + shift:hi + shift], axis=-1)
        if best is None or err.mean() < best[0].mean():
            best = (err, shift)
    return best


@pytest.mark.parametrize("points", [10, 6])
def test_emulated_trackers_over_vmc_give_the_clip_at_60_hz(points):
    motion, frames, counters, source = run_trackers_through_daemon(points, performer())
    assert counters["calibrated"] and counters["frames_solved"] > motion.num_frames
    # One output frame per 60 Hz tick, stamped 1/60 s apart.
    times = np.array([f.sender_time for f in frames])
    assert len(frames) > motion.num_frames - 30 and np.allclose(np.diff(times), 1 / OUTPUT_FPS, atol=1e-5)
    err, shift = solved_error(motion, moving(frames))
    print(f"\n{points} points over VMC: mean {err.mean():.2f} cm, p95 {np.percentile(err, 95):.2f} cm, shift {shift}")
    assert err.mean() <= 2.0 and np.percentile(err, 95) <= 5.0
    # The VMC output carries the calibrated performer's proportions, not the default humanoid.
    assert np.allclose(frames[-1].offsets[1:], source.skeleton.offsets[1:], atol=1e-3)
    assert not np.allclose(frames[-1].offsets[1:], humanoid_skeleton_default().offsets[1:], atol=0.5)


def test_emulated_trackers_of_a_bandai_walk_follow_it():
    """The shipped Bandai walk: its rig splits the spine differently from the humanoid (no
    UpperChest), which a T-pose calibration cannot see, so the spine and the joints hung
    from it sit a few cm off; hands, feet, head and hips stay close."""
    motion, frames, counters, _ = run_trackers_through_daemon(10, walk())
    err, _ = solved_error(motion, moving(frames))
    ends = [HUMANOID_BONES.index(b) for b in ("Hips", "Head", "LeftHand", "RightHand", "LeftFoot", "RightFoot")]
    print(f"\nBandai walk, 10 points over VMC: mean {err.mean():.2f} cm, tracked ends {err[:, ends].mean():.2f} cm")
    assert err.mean() <= 4.0 and err[:, ends].mean() <= 2.0


def test_trackers_that_stop_over_vmc_are_held():
    """VMC has no "lost" flag: a tracker that loses tracking is simply not sent. The
    solver holds its bone (relative to the hips) and blends back when it returns, as it
    does for serial trackers."""
    motion, frames, counters, _ = run_trackers_through_daemon(10, performer(), drop=0.08)
    err, _ = solved_error(motion, moving(frames))
    poses = np.stack([f.pose.rotations for f in frames])
    print(f"\n10 points over VMC, 8 % of samples lost in bursts: mean {err.mean():.2f} cm")
    assert np.isfinite(poses).all() and counters["calibrated"]
    assert err.mean() <= 3.0


def test_calibrate_command_recalibrates_the_vmc_trackers():
    source = open_source("vmc://127.0.0.1:0?points=6", "p0")
    try:
        source.solved.solver = object()  # pretend calibrated
        source.calibrate()
        assert source.solved.solver is None and not source.counters()["calibrated"]
    finally:
        source.close()
    bones = open_source("vmc://127.0.0.1:0?input=bones", "p1")
    try:
        with pytest.raises(UserError, match="bones only"):
            bones.calibrate()
    finally:
        bones.close()


@pytest.mark.parametrize("url, needle", [
    ("vmc://127.0.0.1:0?input=both", "input=both must be one of auto, bones, trackers"),
    ("vmc://127.0.0.1:0?calibrate=sitting", "calibrate=sitting must be tpose or a number of seconds"),
    ("vmc://127.0.0.1:0?roles=LHR-1:elbow", "roles entry 'LHR-1:elbow' must be SERIAL:ROLE"),
    ("vmc://127.0.0.1:0?points=7", "unsupported tracker count 7"),
    ("vmc://127.0.0.1:0?name=a&name=b", "option name is given twice"),
])
def test_bad_tracker_options_are_one_sentence(url, needle):
    with pytest.raises(UserError, match=needle):
        open_source(url, "p0")


def test_role_map_names_trackers_by_serial():
    from stylecast.drivers.trackers.trackers import TrackerRole, parse_role_map, vmc_tracker_role

    roles = parse_role_map("u", "LHR-AAAA:left-foot,LHR-BBBB:waist")
    assert vmc_tracker_role("tra", "LHR-AAAA", roles) is TrackerRole.LEFT_FOOT
    assert vmc_tracker_role("tra", "LHR-BBBB", roles) is TrackerRole.WAIST
    assert vmc_tracker_role("hmd", "LHR-CCCC", roles) is TrackerRole.HMD  # the headset by its address
    assert vmc_tracker_role("tra", "LHR-CCCC", roles) is None


def test_a_calibrated_serial_source_sends_the_performers_own_offsets():
    """serial:// trackers (emulator -> pty -> the daemon's serial source, T-pose
    calibration) -> VMC out: the output carries the calibrated proportions, and FK of the
    output lands on the performer's joints."""
    import os

    from stylecast.drivers.serial.serial_trackers import encode_packets

    from .test_serial_trackers import _raw_master

    motion = performer(3.0)
    rec = emulate_trackers(with_tpose(motion, TPOSE_FRAMES / OUTPUT_FPS), 10)
    master, slave = os.openpty()
    out = VmcReceiver("127.0.0.1", 0)
    daemon = None
    try:
        _raw_master(master)
        source = open_source(f"serial://{os.ttyname(slave)}?points=10&calibrate=tpose", "p0")
        cfg = DaemonConfig(hop=15, control="off", out=["vmc://127.0.0.1:%d" % out.address[1]])
        daemon = Daemon(cfg, [source], IdentityRestyler(), FakeClock(), log_status=False)
        daemon.start()
        frames = []
        for i in range(len(rec) + 40):
            if i < len(rec):
                os.write(master, encode_packets(rec.samples(i)))
                time.sleep(0.002)
            daemon.step()
            daemon.clock.advance(1 / OUTPUT_FPS)
            frames += [f for f in out.poll(0.0) if f.pose is not None]
        for _ in range(20):
            frames += [f for f in out.poll(0.02) if f.pose is not None]
        skeleton = source.skeleton
    finally:
        if daemon is not None:
            daemon.close()
        out.close()
        os.close(master)
        os.close(slave)
    assert skeleton is not None and np.allclose(frames[-1].offsets[1:], skeleton.offsets[1:], atol=1e-3)
    err, _ = solved_error(motion, moving(frames))
    print(f"\nserial 10 points: FK of the VMC output vs the performer's joints, mean {err.mean():.2f} cm")
    assert err.mean() <= 1.0


@pytest.mark.slow
def test_stylecast_emulate_into_stylecast_serve_gives_vmc_out(tmp_path):
    """The issue's report, as a user runs it: `stylecast serve --source vmc://...` and
    `stylecast emulate --to vmc://... --points 10` (real clock, 30 Hz trackers from the
    shipped clip, a T-pose first) -> restyled VMC at 60 Hz with the calibrated proportions."""
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    probe = VmcReceiver("127.0.0.1", 0)
    port_in = probe.address[1]
    probe.close()  # a free port for the daemon's vmc:// source
    out = VmcReceiver("127.0.0.1", 0)
    serve = subprocess.Popen(
        [sys.executable, "-m", "stylecast", "serve", "--source", f"vmc://127.0.0.1:{port_in}?points=10&calibrate=tpose",
         "--out", "vmc://127.0.0.1:%d" % out.address[1], "--model", "identity", "--control", "off",
         "--duration", "30"], cwd=repo, stderr=subprocess.PIPE, text=True)
    frames = []
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            line = serve.stderr.readline()
            if "serving" in line or not line:
                break
        emulate = subprocess.run(
            [sys.executable, "-m", "stylecast", "emulate", "--bvh", str(bundled_clip()), "--to",
             f"vmc://127.0.0.1:{port_in}", "--points", "10", "--tpose", "1.5", "--frames", "180"],
            cwd=repo, capture_output=True, text=True, timeout=60)
        assert emulate.returncode == 0, emulate.stderr
        for _ in range(50):
            frames += [f for f in out.poll(0.02) if f.pose is not None]
    finally:
        serve.terminate()
        serve.communicate(timeout=20)
        out.close()
    assert len(frames) > 120, len(frames)  # 4.5 s of walk less the daemon's delay, at 60 Hz
    steps = np.diff([f.sender_time for f in frames])
    assert np.median(steps) == pytest.approx(1 / OUTPUT_FPS, abs=1e-4)
    hips = np.stack([f.pose.root_position for f in frames])
    assert np.ptp(hips[:, 2]) > 100  # the walk walks (the Bandai walk covers ~4 m in 4.5 s)
    assert not np.allclose(frames[-1].offsets[1:], humanoid_skeleton_default().offsets[1:], atol=0.5)
