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
from dataclasses import replace

import numpy as np

# bench/daemon_rig.py and bench/daemon_capacity.py (scripts run from bench/)
from daemon_capacity import bench_capacity, run_capacity, run_capacity_workers
from daemon_rig import (DATA, FPS, Receiver, ReplaySourceRotations, base_motion, free_ports, indexed_source,
                        make_daemon, option, restyler, run_and_time, table)
from machine import describe  # bench/machine.py

from stylecast.motion.words import DEFAULT_HOP  # serve's default hop


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

    def per_frame(feet, pace, mode, delay=5, overrides=None):
        """CPU ms per performer-frame: "each" one lock, one frame per call (the daemon before
        the per-tick solve); "tick" ``performers`` locks, pushed, planned and solved in one
        call each per tick (the daemon now), with ``delay`` frames of look-ahead (1: the
        lock foresees the rest of its ramp, ``footlock.approach``); "whole" one lock, all
        frames in one call (``restyle``). ``overrides``: ``ContactSettings`` fields to set."""
        count = performers if mode == "tick" else 1
        settings = replace(feet_for(feet, model, pace), **(overrides or {}))
        locks = [FootLock.for_stream(clip.skeleton, delay, settings) for _ in range(count)]
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
    # the stance's offset settling through the blend-in (``stance_settle``) against the frozen
    # offset it replaced, the baseline in the same run; the stance with the quick hips a
    # style asks for (``pelvis_quick_share``: masculine's), two more low-passes a frame; and
    # the feet in the air on the input's path (``swing_path``: an IK for each free leg); and
    # the path with the elderly arm swing and hip bob (``GaitAmplitude``: the multistyle
    # model's towards elderly), the path alone its baseline; and the stance with youthful's
    # amplitudes, the hands' swing across replaced (two arms' forward kinematics and a turn
    # of each upper arm a frame) against the same without it; and active's with its raises'
    # sway (the hands' places and three more low-passes a frame; on the walk the pace gates
    # it off, but it is paid for) against the same without it; and with the runs' elbow bend
    # (the elbows' flexion and a low-pass a frame, paid on the walk too) against the same;
    # and with the walks' hands carried forward (the arms' places, a low-pass and a turn of
    # each upper arm a frame) against the same; and with still arms held (the input arms'
    # places, three low-passes and six bones' offsets a frame, paid on the walk too) against
    # the same; and with waving arms held too (three more low-passes a frame) against the same;
    # and with the knees at feminine's bend too (the knees' flexion, a low-pass and a scale a
    # frame) against the same; and with half of a waving elbow given back too; and with active's
    # walks' elbows carried forward too (the upper arms' directions, a low-pass and a turn of
    # each upper arm a frame) against the same; and with the lean as the performer's too (two
    # spines' forward kinematics, a low-pass and a turn of the spine a frame) against the same
    from stylecast.models.gait_amplitude import amplitudes

    youthful, active, feminine = (amplitudes("normal", {style: 1.0}) for style in ("youthful", "active", "feminine"))
    # the last rows' parts
    elbows, lean = active["elbow_forward"], active["performer_lean"]
    active, youthful = {**active, "elbow_forward": (), "performer_lean": ()}, {**youthful, "performer_lean": ()}
    for feet, overrides, label in (("input", {}, "input"),
                                   ("path", {}, "path (elderly and exhausted)"),
                                   ("path", amplitudes("normal", {"elderly": 1.0}),
                                    "path, elderly arm swing and hip bob"),
                                   ("stance", {"stance_settle": False}, "stance, frozen (before)"),
                                   ("stance", {}, "stance"),
                                   ("stance", {"pelvis_quick_share": 1.0}, "stance, quick hips (masculine)"),
                                   ("stance", {**youthful, "arm_across": ()}, "stance, youthful arm swing and hip bob"),
                                   ("stance", youthful, "stance, youthful, the swing across too"),
                                   ("stance", {**active, "raise_sway": (), "elbow_bend": (), "arm_forward": ()},
                                    "stance, active arm swing and hip bob"),
                                   ("stance", {**active, "elbow_bend": (), "arm_forward": ()},
                                    "stance, active, the raises' sway too"),
                                   ("stance", {**active, "arm_forward": ()}, "stance, active, the runs' elbow bend too"),
                                   ("stance", {**active, "still_arms": ()},
                                    "stance, active, the walks' hands forward too"),
                                   ("stance", active, "stance, active, still arms held too"),
                                   ("stance", {**active, "waving_arms": ((0.0, 1.0),)},
                                    "stance, active, waving arms held too"),
                                   ("stance", {**active, "waving_arms": ((0.0, 1.0),),
                                               "knee_bend": feminine["knee_bend"]},
                                    "stance, active, the knees at feminine's bend too"),
                                   ("stance", {**active, "waving_arms": ((0.0, 1.0),),
                                               "knee_bend": feminine["knee_bend"], "waving_elbows": ((0.0, 0.5),)},
                                    "stance, active, waving elbows half given back too"),
                                   ("stance", {**active, "waving_arms": ((0.0, 1.0),),
                                               "knee_bend": feminine["knee_bend"], "waving_elbows": ((0.0, 0.5),),
                                               "elbow_forward": elbows},
                                    "stance, active, the walks' elbows forward too"),
                                   ("stance", {**active, "waving_arms": ((0.0, 1.0),),
                                               "knee_bend": feminine["knee_bend"], "waving_elbows": ((0.0, 0.5),),
                                               "elbow_forward": elbows, "performer_lean": lean},
                                    "stance, active, the lean as the performer's too")):
        for pace in ("input", "style"):  # the style's pace (footlock.Pace): the carried feet's IK on top
            each, tick, low, whole = (float(np.median([per_frame(feet, pace, mode, delay, overrides)
                                                       for _ in range(runs)]))
                                      for mode, delay in (("each", 5), ("tick", 5), ("tick", 1), ("whole", 5)))
            rows.append((label, pace, f"{each:.3f}", f"{tick:.3f}", f"{low:.3f}", f"{whole:.3f}", f"{each / tick:.1f}x"))
    table(f"Foot lock CPU ms per performer-frame ({n} frames, median of {runs}; the input as the restyle)",
          ["--feet", "--pace", "one lock per call", f"{performers} performers, one solve per tick (daemon)",
           "the same, delay 1 (--latency low)", "all frames in one call (restyle)", "per call / per tick"], rows)


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
