"""``serve --workers N`` (issue 12): performers spread over worker processes; the parent's
control port routes commands and gathers one status for all performers."""

from __future__ import annotations

import queue
import socket
import threading
import time

import pytest
from pythonosc.osc_bundle import OscBundle
from pythonosc.osc_message import OscMessage

from stylecast.daemon.config import DaemonConfig, build_config
from stylecast.daemon.engine import Daemon, grid_start, stagger_phase, worker_offset
from stylecast.daemon.restylers import IdentityRestyler
from stylecast.daemon.workers import merge_snapshots, run_workers, split
from stylecast.drivers.bvh.bvh_replay import ReplaySource
from stylecast.motion.errors import UserError
from stylecast.motion.bvh import write_bvh
from stylecast.motion.clock import OUTPUT_FPS, RealClock

from .test_daemon import walk_clip
from .test_daemon_control import osc


def test_split_is_contiguous_balanced_and_never_empty():
    assert split(5, 2) == [range(0, 2), range(2, 5)] or split(5, 2) == [range(0, 3), range(3, 5)]
    assert split(3, 8) == [range(0, 1), range(1, 2), range(2, 3)]
    parts = split(64, 2)
    assert [len(p) for p in parts] == [32, 32] and parts[0].stop == parts[1].start


def test_serve_runs_one_process_per_core_unless_told_and_never_more_than_performers():
    import os

    cores = len(os.sched_getaffinity(0))
    sources = [f"bvh:///clip{k}.bvh" for k in range(3)]
    assert DaemonConfig(source=sources).validate().processes == min(cores, 3)  # the default, 0
    assert DaemonConfig(source=sources, workers=1).validate().processes == 1
    assert DaemonConfig(source=sources, workers=8).validate().processes == 3
    assert DaemonConfig(source=sources[:1]).validate().processes == 1
    with pytest.raises(UserError, match="one per core"):
        DaemonConfig(source=sources, workers=-1).validate()


def model_call_times(hop: int, performers: int, workers: int) -> list[set[float]]:
    """Per worker process, when in the hop (frame periods after the shared grid) its
    groups hand words to the model: each group's phase plus the worker's clock offset."""
    times, parts = [], split(performers, workers)
    for w, part in enumerate(parts):
        phases = {stagger_phase(hop, k, len(part)) for k in range(len(part))}
        offset = worker_offset(hop, len(phases), w, len(parts))
        times.append({round((phase + offset) % hop, 6) for phase in phases})
    return times


@pytest.mark.parametrize("hop, performers", [(4, 16), (4, 32), (4, 48), (4, 64), (1, 8), (10, 40)])
def test_worker_processes_take_turns_with_the_model(hop, performers):
    """Two workers' model calls never fall on the same moment of the hop (started together,
    as a replay or the capacity bench starts them, both called on the same ticks: up to
    18 ms later results at 16 performers on a 2-core machine, bench/bench_daemon.py)."""
    first, second = model_call_times(hop, performers, 2)
    assert first and second and not first & second
    assert worker_offset(hop, len(first), 0, 2) == 0.0 and worker_offset(hop, len(first), 0, 1) == 0.0
    if performers <= 32:  # a group per phase at most: every call of a process on its own tick
        assert all(len(t) == -(-performers // 2 // 8) for t in (first, second))


def test_a_worker_starts_its_clock_on_the_shared_grid_after_its_offset():
    hop, fps = 4, OUTPUT_FPS
    assert grid_start(10.0, hop, 0.0) * fps / hop == pytest.approx(151.0)  # the next grid point, not this one
    sources = [ReplaySource(walk_clip(120), f"p{k}", loop=True) for k in range(8)]
    daemon = Daemon(DaemonConfig(control="off", status_interval=3600.0), sources, IdentityRestyler(), RealClock(),
                    log_status=False, worker=(1, 2))
    try:
        before = time.monotonic()
        daemon.start()
        offset = worker_offset(daemon.settings.hop, len({s.phase for s in daemon.sessions}), 1, 2)
        assert offset == 2.0  # one group each: the second worker's calls half a hop later
        grid_points = (daemon._t0 - offset / fps) * fps / hop
        assert grid_points == pytest.approx(round(grid_points), abs=1e-6)
        assert before < daemon._t0 <= before + 1.0  # soon: within a grid period of the calibration
    finally:
        daemon.close()


def test_merged_status_lists_every_performer():
    a = {"daemon": {"style": "x", "model": "m", "performers": 2, "ticks": 10, "dropped_ticks": 1, "faults": 0,
                    "control_refused": 0}, "performers": [{"performer": "p0"}, {"performer": "p1"}]}
    b = {"daemon": {**a["daemon"], "performers": 1, "ticks": 12, "dropped_ticks": 2}, "performers": [{"performer": "p2"}]}
    m = merge_snapshots([a, b], control_refused=3)
    assert m["daemon"]["performers"] == 3 and m["daemon"]["dropped_ticks"] == 3 and m["daemon"]["ticks"] == 12
    assert m["daemon"]["control_refused"] == 3 and [p["performer"] for p in m["performers"]] == ["p0", "p1", "p2"]


def messages(datagram: bytes) -> list[tuple[str, list]]:
    if OscBundle.dgram_is_bundle(datagram):
        return [(m.address, m.params) for m in OscBundle(datagram)]
    m = OscMessage(datagram)
    return [(m.address, m.params)]


@pytest.mark.slow
def test_two_workers_serve_four_performers_behind_one_control_port(tmp_path):
    clip = tmp_path / "walk.bvh"
    write_bvh(walk_clip(300), clip)
    cfg = build_config({}, {"source": [f"bvh://{clip}?loop=1"] * 4, "model": "identity", "workers": 2,
                            "control": "127.0.0.1:0", "status_interval": 3600.0})
    stop, started = threading.Event(), queue.Queue()
    runner = threading.Thread(target=run_workers, args=(cfg, stop, started.put), daemon=True)
    runner.start()
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.bind(("127.0.0.1", 0))
    client.settimeout(3.0)
    try:
        control = started.get(timeout=120)
        client.sendto(osc("/stylecast/intensity", 0.5, "p3"), control.address)
        client.sendto(osc("/stylecast/bypass", 1, "nobody"), control.address)  # refused, logged, harmless
        performers = []
        for _ in range(100):  # until the command has reached p3's worker and every clock runs
            client.sendto(osc("/stylecast/status"), control.address)
            reply = messages(client.recvfrom(65536)[0])
            performers = {p[0]: p for a, p in reply if a == "/stylecast/status/performer"}
            if performers.get("p3", [0] * 10)[9] == 0.5 and all(p[2] > 0 for p in performers.values()):
                break
            time.sleep(0.05)
        daemon = [p for a, p in reply if a == "/stylecast/status/daemon"][0]
    finally:
        stop.set()
        runner.join(30)
        client.close()
    assert not runner.is_alive()
    assert sorted(performers) == ["p0", "p1", "p2", "p3"] and daemon[2] == 4
    assert performers["p3"][9] == 0.5 and all(performers[p][9] == 1.0 for p in ("p0", "p1", "p2"))
    assert all(performers[p][2] > 0 for p in performers)  # every worker's clock sent frames
