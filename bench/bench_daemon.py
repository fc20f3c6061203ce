"""Daemon benchmarks: latency, capacity, CPU cost, seam ratio. Prints tables; not a test.

    python bench/bench_daemon.py                # everything (a few minutes)
    python bench/bench_daemon.py latency seams  # a subset: latency capacity cpu seams presets footlock
    python bench/bench_daemon.py presets 8 10   # presets only, 8 performers, 10 s per run
    python bench/bench_daemon.py capacity 5     # capacity only, 5 s per run
    python bench/bench_daemon.py capacity-workers 5  # the same over one process per core (serve --workers)
    python bench/bench_daemon.py capacity-workers 5 --workers 4  # over 4 processes
    python bench/bench_daemon.py capacity-workers 8 --model multistyle  # another model (serve --model)
    python bench/bench_daemon.py capacity-workers 5 --device cuda --sizes 64,256,1024 --no-baseline
                                        # serve --device cuda; rerun with --device cpu for its baseline

Latency: one performer replayed at 60 fps whose hips x position encodes the frame index;
the daemon sends VMC over loopback to a receiver *process* (so its timestamps do not
wait for the daemon's GIL) that decodes the index and stamps the arrival with the
system-wide monotonic clock. Latency = receive time - the moment input frame i arrived
(t0 + i/60 on the same clock). The daemon's own figure (arrival -> sendto returned) is
shown beside it.

Capacity (hop 15): N performers, each to its own port, drained by a receiver process;
N grows until a run drops an output tick (a tick that started more than a whole frame
period late) or shows late words (``--rounds K``: K runs of each size, and a size holds only
if all K do); ``capacity-workers`` spreads them over one process per
core, each a whole daemon over its slice, as ``serve --workers`` does. CPU: process CPU time per performer-second for bypass
and restyle, against a plain python-osc relay (parse every datagram with python-osc,
forward the same bytes) fed the daemon's own packets at the same rate.

Presets (issue 12): N performers (default 8) under each --latency preset, against the
pre-issue-12 behaviour in the same run (hop 15, delay 15, no model timing, no slack
planning): loopback latency p50/p99/max, late frames, dropped ticks, the final delay.

Foot lock (issue 12): CPU per frame of ``FootLock.push`` + ``apply`` on a shared clip,
one frame per call as the daemon runs it (each performer, each tick) against the same
frames in one call (as ``restyle`` runs it): the gap is what vectorising the lock across
performers could win. Median of 5 runs, for ``--feet input`` and ``stance``.

Seams: the paper's d_t (Euclidean distance of a bone's Euler angles, scaled to [-1, 1],
between consecutive frames), mean at frames where the served word changes over mean
elsewhere, on shared Bandai clips, for the live output at hop 15 and hop 1 and for a
non-overlapping baseline (hop 60, no blending). At hop 1 the served word changes on
every frame, so the boundaries counted are those of the 60-frame grid (frames 60k).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import socket
import sys
import time
from pathlib import Path

import numpy as np

from machine import describe  # bench/machine.py (scripts run from bench/)
from processes import run_together  # bench/processes.py

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "bandai"
CHECKPOINT = REPO / "models" / "checkpoints" / "normal2exhausted.safetensors"
from stylecast.motion.clock import OUTPUT_FPS as FPS  # noqa: E402 (the one definition)
from stylecast.motion.words import DEFAULT_HOP  # noqa: E402 (serve's default hop)


# ----------------------------------------------------------------------------- helpers

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


# ----------------------------------------------------------------------------- benches

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


def bench_latency(model, motion, seconds=8.0):
    rows = []
    for hop in (1, 5, 15, 60):
        port = free_ports(1)
        rx = Receiver([port], decode_index=True)
        d = make_daemon(1, hop, model, motion, port, pace="input")  # the receiver reads the index off x
        lat = run_and_time(d, rx, seconds)
        own = d.sessions[0].latency
        goal = hop / FPS * 1e3 + 5
        rows.append((hop, f"{hop / FPS * 1e3:.1f}", f"{np.percentile(lat, 50):.2f}", f"{np.percentile(lat, 99):.2f}",
                     f"{np.max(lat):.2f}", f"{own.percentile(50) * 1e3:.2f}", f"{own.percentile(99) * 1e3:.2f}",
                     f"{goal:.1f}", "yes" if np.percentile(lat, 99) <= goal else "NO",
                     d.sessions[0].blender.late_frames, d.dropped_ticks))
    table("Latency: input frame arrival -> restyled frame received on loopback (ms)",
          ("hop", "delay", "p50", "p99", "max", "daemon p50", "daemon p99", "goal p99", "met", "late", "dropped"),
          rows)


def bench_presets(model, motion, n=8, seconds=8.0):
    rows = []
    for label, hop, latency, legacy, goal in (("before issue 12 (hop 15, delay 15)", 15, "relaxed", True, None),
                                              ("--latency default", 0, "default", False, 100.0),
                                              ("--latency low", 0, "low", False, 35.0)):
        port = free_ports(n)
        rx = Receiver([port + k for k in range(n)], decode_index=True)
        d = make_daemon(n, hop, model, motion, port, latency=latency, legacy=legacy, pace="input")  # index off x
        lat = run_and_time(d, rx, seconds)
        p99 = np.percentile(lat, 99)
        late = sum(s.blender.late_frames for s in d.sessions)
        met = "" if goal is None else ("yes" if p99 <= goal and late == 0 and d.dropped_ticks == 0 else "NO")
        rows.append((label, d.settings.hop, d.settings.delay, f"{np.percentile(lat, 50):.1f}", f"{p99:.1f}",
                     f"{np.max(lat):.1f}", late, d.dropped_ticks, len(d.delay_notes),
                     "" if goal is None else f"<= {goal:.0f}", met))
    table(f"Latency presets, {n} performers, {seconds:.0f} s each (loopback, ms)",
          ("setting", "hop", "final delay", "p50", "p99", "max", "late frames", "dropped ticks", "delay raises",
           "goal p99", "met"), rows)
    workers = os.cpu_count() or 2  # one worker process per core, as serve's default (--workers 0)
    rows = []
    for latency, goal in (("default", 100.0), ("low", 35.0)):
        r = run_capacity_workers(n, workers, seconds, latency=latency)
        met = r["p99"] <= goal and r["late"] == 0 and r["dropped"] == 0
        rows.append((f"--latency {latency} --workers {workers}", r["delay"], f"{r['p99']:.1f}", r["late"], r["dropped"],
                     f"<= {goal:.0f}", "yes" if met else "NO"))
    table(f"Latency presets over {workers} worker processes (one per core), {n} performers, {seconds:.0f} s each "
          f"(ms; the daemon's own measure: input frame arrival -> restyled frame handed to its socket, worst "
          f"performer)", ("setting", "final delay", "p99", "late frames", "dropped ticks", "goal p99", "met"), rows)


def run_capacity(n, model, motion, seconds, bypass=False, hop=15, latency="relaxed", legacy=False, port=None,
                 worker=(0, 1)):
    port = free_ports(n) if port is None else port
    rx = Receiver([port + k for k in range(n)])
    d = make_daemon(n, hop, model, motion, port, bypass=bypass, latency=latency, legacy=legacy, worker=worker)
    cpu0, wall0 = time.process_time(), time.monotonic()
    d.run(duration=seconds)
    cpu, wall = time.process_time() - cpu0, time.monotonic() - wall0
    d.close()
    received, _ = rx.stop()
    late = sum(s.blender.late_frames for s in d.sessions)
    p99 = max(s.latency.percentile(99) for s in d.sessions) * 1e3
    return dict(n=n, dropped=d.dropped_ticks, late=late, delay=d.settings.delay, p99=p99, tick99=d.tick_lateness.percentile(99) * 1e3, cpu=cpu, wall=wall, received=received,
                sent=sum(s.vmc.sender.datagrams_sent for s in d.sinks), busy=d.worker.busy_seconds,
                calls=np.percentile(d.worker.call_ms, 99) if d.worker.call_ms else 0.0)


class PreviousModelCall:
    """The shipped restyler called as the previous releases called it: its operations run
    eagerly, each taking the GIL back from the output loop (``models/pipeline.py``), with
    Python's default 5 ms GIL switch interval and start-up's heap not frozen
    (``engine._settle_heap``). The baseline of the capacity runs (whose worker processes
    also start their clocks together, as before ``engine.worker_offset``)."""

    SWITCH_INTERVAL = 0.005

    def __init__(self, restyler):
        self._restyler = restyler
        self.restyle_words = restyler.restyle_words_eager

    # Nor did it hand the model the words and take back the checked, continuous result in
    # one call (``Restyler.restyle_stream_words``): the worker did that in numpy around it.
    restyle_stream_words = None

    def __getattr__(self, name):
        return getattr(self._restyler, name)


def _capacity_in_process(n, port, seconds, hop, latency, previous, worker, device, model_name, start, conn):
    """One worker of a ``--workers`` capacity run: a whole daemon over its slice, started
    with the others (``start``: a barrier passed once every worker has its model), its
    clock offset as ``serve`` offsets it (``worker``: index, count). ``previous``: the
    previous release's model call (``PreviousModelCall``), every clock started at once.
    ``device``: where this worker's model runs (``serve --device``); ``model_name``: which
    model (None: the shipped default)."""
    model, _ = restyler(device, model_name)
    if previous:
        from stylecast.daemon import engine

        model = PreviousModelCall(model)
        engine.LIVE_SWITCH_INTERVAL = PreviousModelCall.SWITCH_INTERVAL
        engine._settle_heap = lambda: False
    motion = base_motion()
    start.wait()
    conn.send(run_capacity(n, model, motion, seconds, hop=hop, latency=latency, port=port,
                           worker=(0, 1) if previous else worker))
    conn.close()


def run_capacity_workers(n, workers, seconds, hop=0, latency="default", previous=False, device="cpu", model_name=None):
    """``run_capacity`` as ``serve --workers N`` runs it: each process a whole daemon over a
    contiguous slice of the performers (daemon/workers.py), all at once; figures combined."""
    from stylecast.daemon.workers import split

    slices = split(n, workers)
    port = free_ports(n)  # performer k to port + k, whichever worker serves it
    parts = run_together(_capacity_in_process,
                         [(len(r), port + r.start, seconds, hop, latency, previous, (w, len(slices)), device,
                           model_name)
                          for w, r in enumerate(slices)])
    total = {key: sum(p[key] for p in parts) for key in ("dropped", "late", "cpu", "received", "sent")}
    worst = {key: max(p[key] for p in parts) for key in ("delay", "p99", "tick99", "wall", "calls")}
    return dict(n=n, **total, **worst)


def bench_capacity(model, motion, seconds=8.0, workers=1, sizes=(4, 8, 16, 24, 32, 40, 48, 64), device="cpu",
                   baseline=True, rounds=1, model_name=None):
    """Before issue 12 (hop 15, delay 15, no slack planning: the criterion was zero dropped
    ticks, late words were faded) against the default preset (zero dropped ticks AND
    zero late words; the delay may grow, shown). ``workers`` > 1: the default preset only,
    the performers spread over that many processes as ``serve --workers`` does, each
    with its model on ``device``. ``sizes``: the performer counts tried, in order, up to
    the first that fails. ``baseline`` False: the previous releases' run is skipped.
    ``rounds``: runs of each size; a size holds only if every run holds (one run of a
    size on a shared 2-core machine passed or failed by the minute), the table shows
    how many did and the worst run's figures. ``model_name``: the workers' model (None:
    the shipped default), ``model`` the same loaded here."""
    runs = (("before issue 12: hop 15, delay 15", 15, "relaxed", True, False),
            ("--latency default", 0, "default", False, True))
    if workers > 1:  # legacy here: the previous release's model call (PreviousModelCall)
        runs = ((f"--latency default --workers {workers}, as the previous releases ran it (eager model call, GIL "
                 f"switch {PreviousModelCall.SWITCH_INTERVAL * 1e3:g} ms, heap not frozen, clocks started together)",
                 0, "default", True, True),
                (f"--latency default --workers {workers}", 0, "default", False, True))
    if not baseline:
        runs = runs[-1:]
    for label, hop, latency, legacy, strict in runs:
        rows, best = [], 0
        for n in sizes:
            results = []
            for _ in range(rounds):
                if workers > 1:
                    results.append(run_capacity_workers(n, workers, seconds, hop=hop, latency=latency,
                                                        previous=legacy, device=device, model_name=model_name))
                else:
                    results.append(run_capacity(n, model, motion, seconds, hop=hop, latency=latency, legacy=legacy))
            held = sum(x["dropped"] == 0 and (x["late"] == 0 or not strict) for x in results)
            ok = held == rounds
            r = max(results, key=lambda x: (x["dropped"], x["late"], x["p99"]))  # the worst run
            rows.append((n, f"{held}/{rounds}", r["dropped"], r["late"], r["delay"], f"{r['tick99']:.1f}",
                         f"{r['p99']:.1f}", f"{r['calls']:.1f}", f"{r['cpu'] / r['wall'] * 100:.0f}%",
                         f"{r['received']}/{r['sent']}", "ok" if ok else "FAIL"))
            if ok:
                best = n
            else:
                break
        table(f"Capacity, {label} (each run {seconds:.0f} s, {rounds} run(s) a size; figures of the worst)",
              ("performers", "runs held", "dropped ticks", "late frames", "final delay", "tick start p99 ms late",
               "latency p99 ms", "model call p99 ms", "CPU (of 1 core)", "datagrams rx/tx", ""), rows)
        print(f"largest number of performers with zero dropped output frames{' and zero late' if strict else ''}: "
              f"{best}")


def bench_compute(model, motion, seconds=10.0, hops=(DEFAULT_HOP, 15)):
    """Work per tick under a virtual clock (no waiting, no scheduler noise): the whole
    tick, the model included, done serially. A tick costing under 16.7 ms of one core is
    what real time needs, so this bounds capacity on an idle machine from the work alone.
    At serve's default hop and at 15 (the earlier releases' table)."""
    from stylecast.motion.clock import FakeClock
    from stylecast.daemon.config import DaemonConfig
    from stylecast.daemon.engine import Daemon

    for hop in hops:
        rows = []
        for n in (1, 8, 16, 32, 48, 64):
            # Each performer's port bound (and never read: the kernel drops what overflows):
            # a closed port answers every datagram with an ICMP error, which the sender then
            # drains and retries, work no listening client causes (it was in this table
            # before 2026-11-27).
            base = free_ports(n)
            sinks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(n)]
            for k, sink in enumerate(sinks):
                sink.bind(("127.0.0.1", base + k))
            cfg = DaemonConfig(hop=hop, control="off", out=[f"vmc://127.0.0.1:{base}"])
            d = Daemon(cfg, [indexed_source(motion, f"p{k}") for k in range(n)], model, FakeClock(),
                       log_status=False)
            cpu0, wall0 = time.process_time(), time.perf_counter()
            d.run(duration=seconds)
            cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
            d.close()
            for sink in sinks:
                sink.close()
            ticks = d.ticks
            rows.append((n, f"{wall / ticks * 1e3:.2f}", f"{cpu / ticks * 1e3:.2f}", f"{cpu / ticks / n * 1e6:.0f}",
                         f"{d.worker.busy_seconds / ticks * 1e3:.2f}", "yes" if wall / ticks < 1 / FPS else "no"))
        table(f"Work per output tick at hop {hop} under a virtual clock ({seconds:.0f} s of 60 fps content, all "
              f"threads)", ("performers", "wall ms/tick", "CPU ms/tick", "CPU us per performer-frame", "model ms/tick",
                            "fits 16.7 ms"), rows)


def relay_main(listen_port, forward_port, conn):
    """A plain python-osc relay: parse each datagram with python-osc, forward the bytes."""
    import resource
    import socketserver

    from pythonosc import osc_packet

    out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    dest = ("127.0.0.1", forward_port)

    class Handler(socketserver.BaseRequestHandler):
        def handle(self):
            data = self.request[0]
            osc_packet.OscPacket(data)  # what any python-osc receiver does per datagram
            out.sendto(data, dest)

    server = socketserver.UDPServer(("127.0.0.1", listen_port), Handler)
    server.timeout = 0.1
    conn.send("ready")
    start = resource.getrusage(resource.RUSAGE_SELF)
    while not conn.poll():
        server.handle_request()
    end = resource.getrusage(resource.RUSAGE_SELF)
    conn.recv()
    conn.send((end.ru_utime + end.ru_stime) - (start.ru_utime + start.ru_stime))


def bench_cpu(model, motion, n=8, seconds=8.0):
    rows = []
    results = {}
    for label, bypass in (("bypass", True), ("restyle", False)):
        r = run_capacity(n, model, motion, seconds, bypass=bypass)
        results[label] = r
        rows.append((label, f"{r['cpu'] / (n * r['wall']) * 1e3:.2f}", f"{r['cpu'] / r['wall'] * 100:.0f}%",
                     r["dropped"]))
    # The relay floor: feed the daemon's own packets (captured once) at n performers x 60 fps.
    from stylecast.motion.clock import FakeClock
    from stylecast.daemon.config import DaemonConfig
    from stylecast.daemon.engine import Daemon

    frames: list[list[bytes]] = []
    cfg = DaemonConfig(hop=15, control="off", out=["vmc://127.0.0.1:9"])
    d = Daemon(cfg, [indexed_source(motion, "p0")], model, FakeClock(), log_status=False,
               tap=lambda dg: frames.append(list(dg)))
    d.run(duration=2.0)
    d.close()
    ctx = mp.get_context("spawn")
    port = free_ports(2)
    sink = Receiver([port + 1])
    conn, child = ctx.Pipe()
    relay = ctx.Process(target=relay_main, args=(port, port + 1, child), daemon=True)
    relay.start()
    assert conn.recv() == "ready"
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    t0 = time.monotonic()
    tick = 0
    while time.monotonic() - t0 < seconds:
        for _ in range(n):
            for dg in frames[tick % len(frames)]:
                tx.sendto(dg, ("127.0.0.1", port))
        tick += 1
        time.sleep(max(0.0, t0 + tick / FPS - time.monotonic()))
    wall = time.monotonic() - t0
    conn.send("stop")
    cpu = conn.recv()
    relay.join(5)
    sink.stop()
    rows.append(("python-osc relay (floor)", f"{cpu / (n * wall) * 1e3:.2f}", f"{cpu / wall * 100:.0f}%", "-"))
    table(f"CPU per performer-second ({n} performers, hop 15, {seconds:.0f} s; daemon = all its threads)",
          ("mode", "CPU ms per performer-s", "CPU (of 1 core)", "dropped ticks"), rows)


def euler_steps(rotations):
    """The paper's d_t per frame and bone: |euler(t) - euler(t-1)| in [-1, 1] units."""
    from stylecast.motion import rotations as rot

    e = rot.to_euler(rotations, "ZXY") / 180.0
    diff = e[1:] - e[:-1]
    diff = (diff + 1.0) % 2.0 - 1.0  # across the +-180 wrap, take the short way
    return np.linalg.norm(diff, axis=-1)  # (T-1, J): step from frame t-1 to t is row t-1


def seam_sums(out, hop, skip=120):
    """(sum of d_t at boundaries, count, sum elsewhere, count): pooled over clips later."""
    d = euler_steps(out).mean(axis=1)
    boundary = np.zeros(len(d), bool)
    grid = 60 if hop == 1 else hop
    for e in range(59, len(d), grid):
        boundary[e] = True  # the step into frame e + 1, the first frame of the next word
    keep = np.arange(len(d)) >= skip
    b, o = d[boundary & keep], d[~boundary & keep]
    return np.array([b.sum(), len(b), o.sum(), len(o)])


def ratio(sums):
    return (sums[0] / sums[1]) / (sums[2] / sums[3])


def bench_seams(model):
    from stylecast.motion.clock import FakeClock
    from stylecast.daemon.config import DaemonConfig
    from stylecast.daemon.engine import Daemon
    from stylecast.drivers.bvh.bvh_replay import ReplaySource, humanoid_motion
    from stylecast.motion.bvh import read_bvh

    rows, actions, pooled = [], [], {}
    for path in sorted((DATA / "dataset-2" / "data").glob("dataset-2_*_normal_*.bvh.gz")):
        action = path.name.split("_")[1]
        if actions.count(action) >= 2 or len(rows) >= 8:
            continue
        clip = read_bvh(path)
        if clip.duration < 5.0:  # long enough for several words after the start-up fade
            continue
        actions.append(action)
        motion = humanoid_motion(clip)
        row = [path.name.split(".")[0]]
        for col, (hop, decay) in enumerate(((0, 15), (0, 4), (0, 1), (15, -1.0), (4, -1.0), (1, -1.0), (60, 0.0))):
            if hop == 0:  # the input itself, on the hop-15, hop-4 and the 60-frame grid
                sums = seam_sums(ReplaySourceRotations(motion), decay)
                pooled[col] = pooled.get(col, 0) + sums
                row.append(f"{ratio(sums):.3f}")
                continue
            frames = []
            cfg = DaemonConfig(hop=hop, decay=decay, control="off")
            d = Daemon(cfg, [ReplaySource(motion, "p0")], model, FakeClock(), frame_taps=[frames.append],
                       log_status=False)
            d.run()
            d.close()
            sums = seam_sums(np.stack([f.rotations for f in frames]), hop)
            pooled[col] = pooled.get(col, 0) + sums
            row.append(f"{ratio(sums):.3f}")
        rows.append(row)
    rows.append(["ALL (pooled d_t)"] + [f"{ratio(pooled[c]):.3f}" for c in range(7)])
    # Over the input's own ratio on the word grid each column cuts at (short clips' seams are not 1).
    own_grid = {3: 0, 4: 1, 5: 2, 6: 2}
    rows.append(["ALL over the input's"] + [""] * 3 +
                [f"{ratio(pooled[c]) / ratio(pooled[own_grid[c]]):.3f}" for c in range(3, 7)])
    table("Seam ratio of the live output (paper's d_t; the goal: <= 1.02 over the input's on the same grid)",
          ("clip", "input, 15-grid", "input, 4-grid", "input, 60-grid", "hop 15 (relaxed)", "hop 4 (default)",
           "hop 1 (low; 60-grid)", "hop 60 no blend (baseline)"),
          rows)


def bench_footlock(model, motion, runs=5, performers=16):
    from stylecast.motion.footlock import FootLock, feet_for, plan_locks, push_frames, solve_lock_jobs

    clip = motion  # already on the output grid (base_motion)
    rotations, roots = clip.rotations.astype(np.float64), clip.root_positions.astype(np.float64)
    n = len(roots)

    def per_frame(feet, pace, mode, delay=5):
        """CPU ms per performer-frame: "each" one lock, one frame per call (the daemon before
        the per-tick solve); "tick" ``performers`` locks, pushed, planned and solved in one
        call each per tick (the daemon now), with ``delay`` frames of look-ahead (1: the
        lock foresees the rest of its ramp, ``footlock.approach``); "whole" one lock, all
        frames in one call (``restyle``)."""
        count = performers if mode == "tick" else 1
        locks = [FootLock.for_stream(clip.skeleton, delay, feet_for(feet, model, pace)) for _ in range(count)]
        lock = locks[0]
        c0 = time.process_time()
        if mode == "whole":
            lock.push(roots, rotations)
            lock.apply(0, roots[:n - lock.ramp], rotations[:n - lock.ramp], rotations[:n - lock.ramp])
        else:
            for t in range(n):
                k = t - lock.sight
                if mode == "each":
                    lock.push(roots[t:t + 1], rotations[t:t + 1])
                    if k >= 0:
                        lock.apply(k, roots[k:k + 1], rotations[k:k + 1], rotations[k:k + 1])
                    continue
                push_frames([(one, roots[t], rotations[t]) for one in locks])
                if k >= 0:
                    solve_lock_jobs(plan_locks([(one, k, roots[k], rotations[k], rotations[k], None) for one in locks]))
        return (time.process_time() - c0) / (n * count) * 1e3

    rows = []
    for feet in ("input", "stance"):
        for pace in ("input", "style"):  # the style's pace (footlock.Pace): the carried feet's IK on top
            each, tick, low, whole = (float(np.median([per_frame(feet, pace, mode, delay) for _ in range(runs)]))
                                      for mode, delay in (("each", 5), ("tick", 5), ("tick", 1), ("whole", 5)))
            rows.append((feet, pace, f"{each:.3f}", f"{tick:.3f}", f"{low:.3f}", f"{whole:.3f}", f"{each / tick:.1f}x"))
    table(f"Foot lock CPU ms per performer-frame ({n} frames, median of {runs}; the input as the restyle)",
          ["--feet", "--pace", "one lock per call", f"{performers} performers, one solve per tick (daemon)",
           "the same, delay 1 (--latency low)", "all frames in one call (restyle)", "per call / per tick"], rows)


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


def main(argv):
    argv = list(argv)
    device = option(argv, "--device", "cpu")  # where the model runs (serve --device); the tables say
    sizes = option(argv, "--sizes", "")  # performer counts the capacity runs try, comma-separated
    rounds = int(option(argv, "--rounds", 1))  # capacity runs: runs of each size, all must hold
    workers = int(option(argv, "--workers", 0)) or os.cpu_count() or 2  # capacity-workers: serve --workers
    sizes = tuple(int(k) for k in sizes.split(",")) if sizes else (4, 8, 16, 24, 32, 40, 48, 64)
    model_name = option(argv, "--model", None)  # serve --model: a shipped name or a path (default: the shipped one)
    baseline = "--no-baseline" not in argv  # capacity runs: also the previous releases' settings
    argv = [a for a in argv if a != "--no-baseline"]
    from stylecast.models.device import pick_device
    from stylecast.motion.errors import UserError

    try:
        pick_device(device)
    except UserError as exc:
        sys.exit(f"bench_daemon: {exc}")
    numbers = [float(a) for a in argv if a.replace(".", "", 1).isdigit()]
    which = {a for a in argv if not a.replace(".", "", 1).isdigit()} or {"latency", "compute", "capacity", "cpu",
                                                                          "seams", "presets"}
    import scipy

    print("machine: " + describe(f"scipy {scipy.__version__}"))
    model, label = restyler(device, model_name)
    print(f"restyler: {label}")
    motion = base_motion()
    if "latency" in which:
        bench_latency(model, motion)
    if "compute" in which:
        bench_compute(model, motion)
    if "capacity" in which:
        bench_capacity(model, motion, numbers[0] if numbers else 8.0, sizes=sizes, baseline=baseline, rounds=rounds)
    if "capacity-workers" in which:
        bench_capacity(model, motion, numbers[0] if numbers else 8.0, workers=workers, sizes=sizes,
                       device=device, baseline=baseline, rounds=rounds, model_name=model_name)
    if "cpu" in which:
        bench_cpu(model, motion)
    if "presets" in which:
        bench_presets(model, motion, int(numbers[0]) if numbers else 8, numbers[1] if len(numbers) > 1 else 8.0)
    if "seams" in which:
        bench_seams(model)
    if "footlock" in which:
        bench_footlock(model, motion)


if __name__ == "__main__":
    main(sys.argv[1:])
