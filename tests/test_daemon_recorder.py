"""--record: a valid BVH while the daemon runs, on close, and after kill -9 + repair."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from stylecast.motion.clock import FakeClock
from stylecast.daemon.config import DaemonConfig
from stylecast.daemon.engine import Daemon
from stylecast.daemon.restylers import StandInRestyler
from stylecast.drivers.bvh.bvh_recorder import BvhRecorder, repair_bvh
from stylecast.drivers.bvh.bvh_replay import ReplaySource
from stylecast.motion import rotations as rot
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default

from .test_daemon import walk_clip

bvh = pytest.importorskip("stylecast.motion.bvh")
REPO = Path(__file__).resolve().parents[1]


def test_recording_is_a_valid_bvh_of_exactly_what_was_sent(tmp_path):
    frames = []
    path = tmp_path / "out.bvh"
    clip = walk_clip(200)
    daemon = Daemon(DaemonConfig(hop=15, control="off", record=str(path)),
                    [ReplaySource(clip, "p0"), ReplaySource(clip, "p1")], StandInRestyler(), FakeClock(),
                    frame_taps=[lambda f: f.performer == "p0" and frames.append(f)], log_status=False)
    daemon.run()
    daemon.close()
    recorded = bvh.read_bvh(path)
    assert recorded.skeleton.names == HUMANOID_BONES and recorded.fps == pytest.approx(60.0, rel=1e-5)
    assert recorded.num_frames == len(frames) == 200
    sent = np.stack([f.rotations for f in frames])
    assert rot.angle_between(recorded.rotations, sent).max() < 1e-4
    np.testing.assert_allclose(recorded.root_positions, np.stack([f.root_position for f in frames]), atol=1e-5)
    assert bvh.read_bvh(tmp_path / "out.1.bvh").num_frames == 200  # performer 1 beside it


def test_repair_drops_a_cut_last_line_and_fixes_the_count(tmp_path):
    path = tmp_path / "cut.bvh"
    rec = BvhRecorder(path, humanoid_skeleton_default())
    q = rot.from_euler(np.random.default_rng(0).normal(0, 20, (30, 22, 3)), "ZXY")
    for t in range(30):
        rec.append(np.array([t, 90.0, 0.0]), q[t])
    rec.close()
    data = path.read_bytes()
    # what a kill -9 leaves: the count never fixed up (0), the last line half written
    cut = data.replace(b"Frames:         30", b"Frames:          0")[: len(data) - 40]
    path.write_bytes(cut)
    with pytest.raises(Exception):
        assert bvh.read_bvh(path).num_frames == 29
    kept, dropped = repair_bvh(path)
    assert kept == 29 and dropped > 0
    clip = bvh.read_bvh(path)
    assert clip.num_frames == 29
    assert rot.angle_between(clip.rotations, q[:29]).max() < 1e-4
    assert repair_bvh(path) == (29, 0)  # idempotent


def test_kill_9_while_recording_loses_at_most_a_second_and_repairs(tmp_path):
    path = tmp_path / "live.bvh"
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(REPO / 'tests')!r})
        from stylecast.motion.clock import RealClock
        from stylecast.daemon.config import DaemonConfig
        from stylecast.daemon.engine import Daemon
        from stylecast.daemon.restylers import StandInRestyler
        from stylecast.drivers.bvh.bvh_replay import ReplaySource
        from tests.test_daemon import walk_clip
        d = Daemon(DaemonConfig(hop=15, control="off", record={str(path)!r}),
                   [ReplaySource(walk_clip(120), "p0", loop=True)], StandInRestyler(), RealClock(),
                   log_status=False)
        print("started", flush=True)
        d.run(duration=30)
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=REPO, stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "started"
    time.sleep(1.5)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=5)
    kept, _ = repair_bvh(path)
    clip = bvh.read_bvh(path)
    assert clip.num_frames == kept
    assert kept >= 60 * 1.5 - 15 - 60  # everything but the delay and at most one second
