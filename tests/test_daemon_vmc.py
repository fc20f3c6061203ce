"""The daemon's VMC output, received over real loopback UDP by an independent OSC
implementation: liblo's ``oscdump`` (Debian liblo-tools)."""

from __future__ import annotations

import shutil
import socket
import subprocess
import threading
import time

import numpy as np
import pytest
from pythonosc.osc_message_builder import OscMessageBuilder

from stylecast.motion.clock import RealClock
from stylecast.daemon.config import DaemonConfig
from stylecast.daemon.engine import Daemon
from stylecast.daemon.restylers import StandInRestyler
from stylecast.drivers.bvh.bvh_replay import ReplaySource
from stylecast.motion.humanoid import HUMANOID_BONES

from .test_daemon import walk_clip

OSCDUMP = shutil.which("oscdump")


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_oscdump() -> tuple[subprocess.Popen, list[str], int]:
    """oscdump on a free port, the list its output lines are collected into, and the port;
    returns once it has printed a probe message (so no frame is sent before it listens).
    Another process can take the port between ``free_udp_port`` and oscdump's bind (a full
    run under load once saw oscdump print nothing for 5 s): then a new port is tried."""
    probe = OscMessageBuilder("/probe").build().dgram
    for _attempt in range(3):
        port = free_udp_port()
        proc = subprocess.Popen([OSCDUMP, "-L", str(port)], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                text=True)
        lines: list[str] = []
        proc.reader = threading.Thread(target=lambda out=proc.stdout, sink=lines: sink.extend(iter(out.readline, "")),
                                       daemon=True)
        proc.reader.start()
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for _ in range(200):
                s.sendto(probe, ("127.0.0.1", port))
                time.sleep(0.025)
                if lines:
                    return proc, lines, port
                if proc.poll() is not None:
                    break
        proc.kill()
    raise AssertionError("oscdump did not start on any of three ports")


@pytest.mark.skipif(OSCDUMP is None, reason="oscdump (liblo-tools) is not installed")
@pytest.mark.parametrize("bundled", [True, False])
def test_oscdump_receives_vmc_frames_at_60_hz(bundled):
    dump, received, port = start_oscdump()
    try:
        cfg = DaemonConfig(hop=5, control="off", out=[f"vmc://127.0.0.1:{port}"], bundled=bundled)
        daemon = Daemon(cfg, [ReplaySource(walk_clip(120), "p0", loop=True)], StandInRestyler(), RealClock(),
                        log_status=False)
        daemon.run(duration=1.0)
        daemon.close()
        sent = daemon.sinks[0].vmc.sender
        # 60 ticks less the delay (5; on a busy machine the planner may raise it, one status line,
        # and the output holds a tick for each frame: CI, 2026-12-07, 6)
        assert sent.frames_sent == 60 - daemon.settings.delay and sent.datagrams_sent >= 2 * sent.frames_sent
        time.sleep(0.3)
    finally:
        dump.terminate()
        dump.wait(timeout=5)
        dump.reader.join(timeout=5)  # every line printed before the exit is in `received`
    lines = [line.split() for line in received if line.strip() and "/probe" not in line]
    assert lines, "oscdump received nothing"
    by_address: dict[str, list[list[str]]] = {}
    for fields in lines:
        by_address.setdefault(fields[1], []).append(fields)
    assert set(by_address) == {"/VMC/Ext/Root/Pos", "/VMC/Ext/Bone/Pos", "/VMC/Ext/OK", "/VMC/Ext/T"}
    frames = len(by_address["/VMC/Ext/T"])
    assert frames == sent.frames_sent  # every frame arrived (loopback does not lose datagrams at this rate)
    assert all(f[2] == "sfffffff" and f[3] == '"root"' for f in by_address["/VMC/Ext/Root/Pos"])
    bones = [f[3].strip('"') for f in by_address["/VMC/Ext/Bone/Pos"]]
    assert all(f[2] == "sfffffff" for f in by_address["/VMC/Ext/Bone/Pos"])
    assert bones == list(HUMANOID_BONES) * frames  # every bone, in order, every frame
    values = np.array([[float(v) for v in f[4:11]] for f in by_address["/VMC/Ext/Bone/Pos"]])
    assert np.allclose(np.linalg.norm(values[:, 3:], axis=1), 1.0, atol=1e-4)  # unit quaternions
    assert all(f[2] == "iiii" for f in by_address["/VMC/Ext/OK"])
    times = np.array([float(f[3]) for f in by_address["/VMC/Ext/T"]])
    assert by_address["/VMC/Ext/T"][0][2] == "f"
    np.testing.assert_allclose(np.diff(times), 1 / 60, atol=2e-6)  # a steady 60 Hz clock
