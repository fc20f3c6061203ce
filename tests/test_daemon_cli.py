"""`stylecast serve`, `demo` and `repair` as a user runs them (subprocesses, real clock)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from .test_sources import WALK

REPO = Path(__file__).resolve().parents[1]


def stylecast(*args, **kwargs):
    return subprocess.run([sys.executable, "-m", "stylecast", *args], cwd=REPO, capture_output=True, text=True,
                          timeout=120, **kwargs)


def test_serve_refuses_bad_input_with_one_sentence():
    r = stylecast("serve", "--source", "bvh:///x.bvh?lop=1", "--control", "off")
    assert r.returncode == 2 and "unknown option lop" in r.stderr and "Traceback" not in r.stderr
    r = stylecast("serve", "--source", "bvh:///nope.bvh", "--out", "osc://127.0.0.1:1", "--control", "off")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    r = stylecast("serve", "--source", "bvh:///nope.bvh", "--feet", "glued", "--control", "off")
    assert r.returncode == 2 and "--feet 'glued' is not known; use one of auto, input, stance" in r.stderr
    assert r.stderr.count("\n") == 1
    r = stylecast("serve", "--source", "bvh:///nope.bvh", "--pace", "brisk", "--control", "off")
    assert r.returncode == 2 and "--pace 'brisk' is not known; use one of style, input" in r.stderr
    assert r.stderr.count("\n") == 1


@pytest.mark.skipif(not WALK.exists(), reason="shared Bandai data not present")
def test_sigterm_stops_serve_cleanly_with_a_valid_recording(tmp_path):
    bvh = pytest.importorskip("stylecast.motion.bvh")
    out = tmp_path / "rec.bvh"
    proc = subprocess.Popen([sys.executable, "-m", "stylecast", "serve", "--source", f"bvh://{WALK}?loop=1",
                             "--model", "identity", "--out", "vmc://127.0.0.1:39999", "--record", str(out),
                             "--control", "127.0.0.1:0", "--status-interval", "0.5"],
                            cwd=REPO, stderr=subprocess.PIPE, text=True)
    # Signal only once it is serving (imports can take seconds on a loaded machine), then
    # let it stream for a while.
    first = []
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = proc.stderr.readline()
        first.append(line)
        if "serving" in line or not line:
            break
    time.sleep(1.5)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=20)
    err = "".join(first) + err
    assert proc.returncode == 0, err
    assert "p0: in" in err and "recording closed" in err
    assert bvh.read_bvh(out).num_frames > 30


@pytest.mark.skipif(not WALK.exists(), reason="shared Bandai data not present")
def test_demo_runs_for_a_duration_and_stops(tmp_path):
    bvh = pytest.importorskip("stylecast.motion.bvh")
    out = tmp_path / "demo.bvh"
    r = stylecast("demo", "--duration", "1.5", "--record", str(out), "--control", "off", "--status-interval", "1")
    assert r.returncode == 0, r.stderr
    assert "replaying" in r.stderr and "p0" not in r.stderr.split("replaying")[0]
    assert bvh.read_bvh(out).num_frames >= 60


def test_repair_command(tmp_path):
    import numpy as np

    from stylecast.drivers.bvh.bvh_recorder import BvhRecorder
    from stylecast.motion.humanoid import humanoid_skeleton_default

    path = tmp_path / "r.bvh"
    rec = BvhRecorder(path, humanoid_skeleton_default())
    for t in range(5):
        rec.append(np.zeros(3), np.tile([0.0, 0.0, 0.0, 1.0], (22, 1)))
    rec.close()
    r = stylecast("repair", str(path))
    assert r.returncode == 0 and "5 frames kept" in r.stdout
