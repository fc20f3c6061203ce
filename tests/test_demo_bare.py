"""`stylecast demo` on a bare machine: a fresh clone, a fresh virtual environment, no
``../shared`` beside it. The demo must fall back to the clip shipped as package data and
send VMC."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from stylecast.drivers.vmc.osc_packets import decode

REPO = Path(__file__).resolve().parents[1]


def test_shipped_clips_are_in_the_package_with_their_attribution():
    from stylecast.daemon.clips import BUNDLED, CLIPS_DIR, bundled_clip
    from stylecast.motion.bvh import read_bvh

    total = sum((CLIPS_DIR / name).stat().st_size for name in BUNDLED)
    assert total < 300_000  # "a few hundred KB at most"
    clip = read_bvh(bundled_clip())
    assert clip.fps == 30.0 and clip.num_frames > 150 and "Hips" in clip.skeleton.names
    note = (CLIPS_DIR / "ATTRIBUTION.md").read_text()
    assert "arXiv:2306.08861" in note and "CC BY-NC 4.0" in note


def test_shipped_clip_is_the_dataset_clip(bandai_root):
    import numpy as np

    from stylecast.daemon.clips import BUNDLED, CLIPS_DIR
    from stylecast.motion.bvh import read_bvh

    for name, relative in BUNDLED.items():
        shipped, original = read_bvh(CLIPS_DIR / name), read_bvh(bandai_root.parent / relative)
        assert shipped.num_frames == original.num_frames
        assert np.allclose(shipped.root_positions, original.root_positions, atol=1e-3)
        dots = np.abs(np.sum(shipped.rotations * original.rotations, axis=-1))
        assert dots.min() > 1 - 1e-6


def _vmc_listener() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(0.5)
    return sock


@pytest.mark.slow
def test_demo_runs_from_a_fresh_clone_without_shared_data(tmp_path):
    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    clone = tmp_path / "stylecast"
    # A clone holds only what is committed: exactly what a new user gets.
    subprocess.run(["git", "clone", "--quiet", str(REPO), str(clone)], check=True, timeout=120)
    assert not (tmp_path / "shared").exists()
    # --system-site-packages + --no-deps: CI already has torch and the other dependencies
    # installed, and downloading torch again would cost minutes and GBs. --without-pip: the
    # venv's bundled setuptools can be older than the system's (no bdist_wheel), so the
    # system pip and setuptools build the package into the new environment.
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", str(venv)],
                   check=True, timeout=120)
    python = venv / "bin" / "python"
    subprocess.run([str(python), "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                    str(clone)], check=True, timeout=300, cwd=tmp_path, capture_output=True)
    where = subprocess.run([str(python), "-c", "import stylecast.daemon.clips as c; print(c.__file__)"],
                           check=True, capture_output=True, text=True, cwd=tmp_path).stdout.strip()
    assert where.startswith(str(venv)), f"stylecast imported from {where}, not the new environment"

    sock = _vmc_listener()
    port = sock.getsockname()[1]
    env = {k: v for k, v in os.environ.items() if k != "STYLECAST_DATA"}
    proc = subprocess.Popen([str(venv / "bin" / "stylecast"), "demo", "--duration", "5", "--no-view",
                             "--out", f"vmc://127.0.0.1:{port}", "--control", "off"],
                            cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    bones, addresses = 0, set()
    deadline = time.monotonic() + 240
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                data, _ = sock.recvfrom(65536)
            except socket.timeout:
                continue
            for address, _tags, args in decode(data, lambda reason: None)[1]:
                addresses.add(address)
                bones += address == "/VMC/Ext/Bone/Pos"
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        sock.close()
    assert proc.returncode == 0, err
    assert "walk_normal.bvh.gz" in err and "clips" in err  # the shipped clip, not ../shared
    assert {"/VMC/Ext/Root/Pos", "/VMC/Ext/Bone/Pos", "/VMC/Ext/OK"} <= addresses
    # 5 s at 60 Hz with 21 bones per frame, less the start-up delay and a loaded machine's slack
    assert bones >= 21 * 60 * 3, bones
