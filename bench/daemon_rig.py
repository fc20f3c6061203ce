"""What the daemon benchmarks share (``bench_daemon.py``, ``daemon_capacity.py``): the model
and motion they run, a replay whose hips carry the frame index, a receiver process that
drains (and stamps) the daemon's output, free loopback ports, a daemon built as ``serve``
builds it, the latency of a run, and the table every bench prints."""

from __future__ import annotations

import multiprocessing as mp
import socket
import sys
import time
from pathlib import Path

import numpy as np

from stylecast.motion.clock import OUTPUT_FPS as FPS  # the one definition

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "bandai"
CHECKPOINT = REPO / "models" / "checkpoints" / "normal2exhausted.safetensors"


def restyler(device="cpu", name=None):
    """The shipped default model, or the model ``name`` (``--model``: a shipped name or a
    path, as ``serve --model`` takes it)."""
    from stylecast.daemon.restylers import StandInRestyler

    if name:
        from stylecast.models.restyler import Restyler

        model = Restyler.load(name, device=device)
        return model, f"{model.name} on {model.device}"
    if CHECKPOINT.exists():
        from stylecast.models.restyler import Restyler

        model = Restyler.load(str(CHECKPOINT), device=device)
        return model, f"normal2exhausted (shipped model) on {model.device}"
    return StandInRestyler(), "stand-in restyler (numpy; the model checkpoint is not shipped yet)"


def base_motion():
    """A Bandai walk as humanoid motion, or a synthetic one if the data is absent."""
    from stylecast.drivers.bvh.bvh_replay import humanoid_motion
    from stylecast.motion.bvh import read_bvh

    from stylecast.motion.resample import resample

    walk = DATA / "dataset-2" / "data" / "dataset-2_walk_normal_001.bvh.gz"
    if walk.exists():
        # At the output rate, so one replayed frame is one stream frame (indexed_source).
        return resample(humanoid_motion(read_bvh(walk)), FPS)
    sys.path.insert(0, str(REPO))
    from tests.test_daemon import walk_clip

    return walk_clip(600)


def indexed_source(motion, name):
    """A looping replay whose hips x position (cm) is 10 x the stream frame index."""
    from stylecast.drivers.bvh.bvh_replay import ReplaySource
    from stylecast.motion.clip import PoseFrame

    class Indexed(ReplaySource):
        def poll(self, now):
            out = []
            for f in super().poll(now):
                i = round((f.timestamp - self._t0) * FPS)
                out.append(PoseFrame(f.performer, f.timestamp, np.array([10.0 * i, 90.0, 0.0]), f.rotations))
            return out

    return Indexed(motion, name, loop=True)


def receiver_main(ports, conn, decode_index):
    """Receiver process: drain ports; optionally stamp (frame index, monotonic time)."""
    import selectors
    import struct

    sel = selectors.DefaultSelector()
    socks = []
    for p in ports:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        s.bind(("127.0.0.1", p))
        s.setblocking(False)
        sel.register(s, selectors.EVENT_READ)
        socks.append(s)
    conn.send("ready")
    marker = b"Hips\x00\x00\x00\x00"
    stamps, count = [], 0
    while not conn.poll():
        for key, _ in sel.select(0.1):
            while True:
                try:
                    data = key.fileobj.recv(65536)
                except BlockingIOError:
                    break
                count += 1
                if decode_index:
                    at = data.find(marker)
                    if at >= 0:
                        x = struct.unpack_from(">f", data, at + len(marker))[0]
                        stamps.append((round(-x * 10), time.monotonic()))  # Unity x = -x_cm / 100
    conn.recv()
    conn.send((count, stamps))


class Receiver:
    def __init__(self, ports, decode_index=False):
        ctx = mp.get_context("spawn")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=receiver_main, args=(ports, child, decode_index), daemon=True)
        self.proc.start()
        assert self.conn.recv() == "ready"

    def stop(self):
        self.conn.send("stop")
        result = self.conn.recv()
        self.proc.join(5)
        return result


def free_ports(n):
    """A run of n consecutive free UDP ports (performer k goes to base + k)."""
    for base in range(41000, 60000, 97):
        try:
            socks = []
            for k in range(n):
                s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                socks.append(s)
                s.bind(("127.0.0.1", base + k))
            return base
        except OSError:
            continue
        finally:
            for s in socks:
                s.close()
    raise RuntimeError("no free port range")


def table(title, header, rows):
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows)]
    line = lambda r: "| " + " | ".join(str(x).ljust(w) for x, w in zip(r, widths)) + " |"  # noqa: E731
    print(f"\n{title}\n" + line(header) + "\n|" + "|".join("-" * (w + 2) for w in widths) + "|")
    for r in rows:
        print(line(r))


def make_daemon(n, hop, model, motion, port, bypass=False, duration_hint=0.0, latency="default", legacy=False,
                worker=(0, 1), pace="style"):
    """hop 0: the latency preset's hop and delay. ``legacy``: as before issue 12 (no model
    timing before the start, no slack planning while running). ``worker``: the daemon's
    index among that many worker processes (``serve --workers``). ``pace``: ``serve
    --pace``; a receiver that reads the frame index off the root's x needs "input" (the
    style's pace shortens the path, so x no longer says which frame it is)."""
    from stylecast.motion.clock import RealClock
    from stylecast.daemon.config import DaemonConfig
    from stylecast.daemon.engine import Daemon

    cfg = DaemonConfig(hop=hop, latency=latency, control="off", out=[f"vmc://127.0.0.1:{port}"], bypass=bypass,
                       pace=pace)
    sources = [indexed_source(motion, f"p{k}") for k in range(n)]
    d = Daemon(cfg, sources, model, RealClock(), log_status=False, worker=worker)
    if legacy:
        d._calibrate = d._plan_slack = lambda: None
    return d


def run_and_time(d, rx, seconds):
    """Run daemon ``d`` for ``seconds`` and return the added latency (ms) of each frame
    ``rx`` received: receive time against the input frame's due time; the start-up
    second skipped."""
    d.run(duration=seconds)
    t0 = d.sessions[0].source._t0
    d.close()
    _, stamps = rx.stop()
    lat = np.array([t - (t0 + i / FPS) for i, t in stamps]) * 1e3
    return lat[len(lat) // 10:]


def ReplaySourceRotations(motion):  # noqa: N802 (reads like the source it stands for)
    """The rotations the daemon's sessions see: the motion on the 60 Hz output grid."""
    from stylecast.motion.resample import resample

    return resample(motion, FPS).rotations


def option(argv, name, default):
    """``--name VALUE`` out of argv (removed from it), else ``default``."""
    if name in argv:
        at = argv.index(name)
        value = argv[at + 1]
        del argv[at:at + 2]
        return value
    return default
