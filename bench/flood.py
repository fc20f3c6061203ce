"""Flood bench: junk datagrams at 50,000/s on loopback beside 8 live VMC performers. Not a test.

    python bench/flood.py                          # 20 s, 50,000 junk/s, 8 performers, junk on their ports
    python bench/flood.py --seconds 10 --rate 20000 --performers 4 --junk-to separate

Everything stays on 127.0.0.1 and is bounded in time. Processes:

* the daemon (this process, real clock, the stand-in restyler or the shipped model):
  one ``vmc://`` source per performer, a control port, VMC out to one port per performer;
* one process replaying a Bandai walk as ``--performers`` VMC senders at 60 fps, each
  frame's /VMC/Ext/T carrying its index;
* ``--junk-senders`` processes sending junk round-robin to the performers' own input
  ports (``--junk-to legit``: the hard case, junk and frames share a socket) or to one
  extra junk-only input port (``--junk-to separate``), and to the control port. The junk
  is made of datagrams each rejected with exactly one counted reason (tests/hardening_junk.py),
  so "reasons counted == junk datagrams read" is exact;
* one process receiving the daemon's VMC output on every performer's port.

Reported: junk rate achieved; junk read and counted by the daemon, and junk the kernel
dropped before the daemon read it (full receive buffer); per performer, legit input
frames sent / read by the daemon, output frames sent / received and missing output ticks
(a missing tick = a tick the overloaded daemon dropped, counted, or a datagram lost);
peak RSS; log records. ``run_flood`` is also used by tests/test_hardening_flood.py.
"""

from __future__ import annotations

import argparse
import logging
import multiprocessing as mp
import sys
import threading
import time
from collections import Counter
from pathlib import Path

import numpy as np


REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests import hardening_junk as hj  # noqa: E402

DATA = REPO.parent / "shared" / "data" / "bandai"
VMC_REASONS = ("empty", "not_osc", "truncated", "bad_padding", "bad_address", "bad_string", "bad_type_tag",
               "trailing_bytes", "bad_bundle_header", "bad_element_size", "oversized_element", "nested_bundle",
               "wrong_type", "missing_args", "non_finite", "bad_quaternion", "unknown_address", "ignored_vmc",
               "ignored_bone", "too_many_performers")


class CountingHandler(logging.Handler):
    def __init__(self):
        super().__init__(logging.DEBUG)
        self.records = Counter()
        self.samples: list[str] = []

    def emit(self, record):
        self.records[record.levelname] += 1
        if len(self.samples) < 20:
            self.samples.append(record.getMessage()[:120])


def walk_stream():
    """A humanoid walk as 60 fps arrays (Bandai if present, else synthetic)."""
    from stylecast.drivers.bvh.bvh_replay import ReplaySource, humanoid_motion
    from stylecast.motion.bvh import read_bvh

    walk = DATA / "dataset-2" / "data" / "dataset-2_walk_normal_001.bvh.gz"
    if walk.exists():
        motion, name = humanoid_motion(read_bvh(walk)), walk.name
    else:
        from tests.test_daemon import walk_clip

        motion, name = walk_clip(600), "synthetic walk"
    from stylecast.motion.clock import OUTPUT_FPS
    from stylecast.motion.resample import resample

    stream = ReplaySource(resample(motion, OUTPUT_FPS), "x", loop=True)  # the sessions' 60 Hz view
    return motion, stream.rotations, stream.root_positions, name


def pick_restyler(name: str):
    from stylecast.daemon.restylers import load_restyler

    return load_restyler(name)


def run_flood(seconds: float = 20.0, rate: float = 50_000, performers: int = 8, replays: int = 0,
              junk_to: str = "legit", junk_senders: int = 2, restyler: str = "standin", hop: int = 15,
              quiet: bool = False) -> dict:
    """Run one flood; return every figure (see the module docstring)."""
    from stylecast.motion.clock import RealClock
    from stylecast.daemon.config import DaemonConfig
    from stylecast.daemon.engine import Daemon
    from stylecast.drivers.bvh.bvh_replay import ReplaySource
    from stylecast.drivers.sources import open_source
    from stylecast.motion.humanoid import humanoid_skeleton_default

    ctx = mp.get_context("fork")  # children need only what they are handed
    motion, rotations, roots, clip_name = walk_stream()
    vmc_junk, vmc_expected = hj.single_reason_junk("vmc", 20_000, seed=5)
    ctl_junk, ctl_expected = hj.single_reason_junk("control", 5_000, seed=6)

    sources = [open_source(f"vmc://127.0.0.1:0?name=live{k}", f"live{k}") for k in range(performers)]
    sources += [ReplaySource(motion, f"replay{k}", loop=True) for k in range(replays)]
    junk_source = None
    if junk_to == "separate":
        junk_source = open_source("vmc://127.0.0.1:0?name=junk", "junk")
        sources.append(junk_source)
    n_out = len(sources)
    out_socks = hj.bind_consecutive(n_out)
    base = out_socks[0].getsockname()[1]
    cfg = DaemonConfig(hop=hop, control="127.0.0.1:0", out=[f"vmc://127.0.0.1:{base}"], status_interval=3600.0)
    stop = threading.Event()
    indices: dict[str, list] = {}
    previous: dict[str, object] = {}

    def tap(f):  # new frames only (a held tick re-sends the previous frame object)
        if previous.get(f.performer) is not f:
            indices.setdefault(f.performer, []).append(f.index)
        previous[f.performer] = f

    daemon = Daemon(cfg, sources, pick_restyler(restyler), RealClock(stop), log_status=False, frame_taps=[tap])
    control = daemon.control.address
    live_ports = [s.receiver.address for s in sources[:performers]]
    address_of = {id(s): f"{s.receiver.address[0]}:{s.receiver.address[1]}" for s in sources
                  if hasattr(s, "receiver")}
    junk_ports = live_ports if junk_to == "legit" else [junk_source.receiver.address]
    streams = [(p, vmc_junk) for p in junk_ports] + [(control, ctl_junk)]

    results = ctx.Queue()
    go = ctx.Event()
    ready = ctx.Event()
    offsets = humanoid_skeleton_default().offsets
    procs = [ctx.Process(target=hj.vmc_frame_receiver, args=(out_socks, seconds + 4.0, ready, results))]
    if performers:
        procs.append(ctx.Process(target=hj.vmc_performers_sender,
                                 args=(live_ports, rotations, roots, offsets, seconds, go, results)))
    for k in range(junk_senders):
        procs.append(ctx.Process(target=hj.junk_sender,
                                 args=(streams[k::junk_senders] or streams, rate / junk_senders, seconds, go,
                                       results)))
    handler = CountingHandler()
    logger = logging.getLogger("stylecast")
    old_level = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:  # reset VmHWM, so the peak reported is this run's (Linux: clear_refs 5)
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass
    rss0, _ = hj.peak_rss_mb()
    drops0 = hj.udp_rcvbuf_errors()
    try:
        for p in procs:
            p.start()
        for s in out_socks:
            s.close()  # the receiver process has its own copies
        ready.wait(30)
        daemon.start()
        go.set()
        t0, cpu0 = time.monotonic(), time.process_time()
        daemon.run(stop, duration=seconds + 1.0)
        wall, cpu = time.monotonic() - t0, time.process_time() - cpu0
        alive = (daemon.control._thread.is_alive()
                 and all(s.receiver._thread is None or s.receiver._thread.is_alive()
                      for s in sources if hasattr(s, "receiver")))
        snapshot = daemon.snapshot()
    finally:
        daemon.close()
        logger.removeHandler(handler)
        logger.setLevel(old_level)
    got = {}
    for _ in range(len(procs)):
        item = results.get(timeout=60)
        got.setdefault(item[0], []).append(item[1:])
    for p in procs:
        p.join(timeout=10)
    rss1, hwm = hj.peak_rss_mb()
    drops1 = hj.udp_rcvbuf_errors()

    junk_sent = Counter()
    junk_elapsed = []
    for sent, elapsed in got.get("junk", []):
        junk_sent.update(sent)
        junk_elapsed.append(elapsed)
    legit_sent = got["legit"][0][0] if "legit" in got else {}
    received = got["received"][0][0]
    per = []
    for k, (s, sinks) in enumerate(zip(daemon.sessions, daemon.sinks)):
        counters = s.source.counters()
        reasons = sum(counters.get(r, 0) for r in VMC_REASONS)
        key = address_of.get(id(s.source))
        ticks = sorted(round(t * 60) for t in received.get(base + k, []))
        first = ticks[0] if ticks else 0
        expected_ticks = daemon.ticks - first
        per.append({
            "performer": s.performer, "kind": "junk" if s is not None and s.source is junk_source else
            ("live" if key else "replay"),
            "legit_sent": legit_sent.get(key, 0) if key else None,
            # frames ended by their /VMC/Ext/T (a frame whose two bundles arrived > 50 ms apart
            # is completed early by expiry and again by its T: that counts once here)
            "legit_read": (counters.get("frames", 0) - counters.get("expired_frames", 0) if key else s.frames_in),
            "junk_sent": junk_sent.get(key, 0) if key else 0,
            "junk_counted": reasons, "datagrams_read": counters.get("datagrams", 0),
            "index_gaps": int(np.sum(np.diff(indices.get(s.performer, [0])) - 1)),
            "frames_in": s.frames_in, "out_sent": sinks.vmc.sender.frames_sent, "out_received": len(ticks),
            "out_missing_ticks": expected_ticks - len(ticks), "held": s.held, "skipped": s.skipped,
            "dropped": s.dropped, "late": s.blender.late_frames,
            "latency_p99_ms": s.latency.percentile(99) * 1e3,
        })
    control_key = f"{control[0]}:{control[1]}"
    control_counted = sum(v for k, v in daemon.control.counts.items() if k.startswith("malformed_")
                          or k in ("unknown_address", "bad_arguments", "queue_full"))
    total_junk_sent = sum(junk_sent.values())
    total_counted = control_counted + sum(p["junk_counted"] for p in per)
    result = {
        "seconds": seconds, "wall": wall, "daemon_cpu_s": cpu, "clip": clip_name, "restyler": daemon.style,
        "rate_target": rate, "rate_achieved": total_junk_sent / max(max(junk_elapsed or [seconds]), 1e-9),
        "junk_sent": total_junk_sent, "junk_counted": total_counted,
        "junk_dropped_by_kernel": total_junk_sent - total_counted,
        "kernel_rcvbuf_errors": drops1 - drops0 if drops0 >= 0 else None,
        "control": {"sent": junk_sent.get(control_key, 0), "read": daemon.control.counts["datagrams"],
                    "counted": control_counted},
        "performers": per, "ticks": daemon.ticks, "dropped_ticks": daemon.dropped_ticks,
        "tick_late_p99_ms": daemon.tick_lateness.percentile(99) * 1e3,
        "rss_before_mb": rss0, "rss_after_mb": rss1, "peak_rss_mb": hwm,
        "log_records": dict(handler.records), "log_samples": handler.samples, "alive": alive,
        "snapshot": snapshot, "expected_vmc_reasons": vmc_expected, "expected_control_reasons": ctl_expected,
    }
    if not quiet:
        print_report(result)
    return result


def print_report(r: dict) -> None:
    print(f"flood: {r['seconds']:.0f} s ({r['wall']:.1f} s wall, daemon process CPU {r['daemon_cpu_s']:.1f} s), clip {r['clip']}, restyler {r['restyler']}")
    print(f"junk: target {r['rate_target']:,.0f}/s, achieved {r['rate_achieved']:,.0f}/s; sent {r['junk_sent']:,}, "
          f"read and counted by reason {r['junk_counted']:,}, dropped by the kernel before the daemon read them "
          f"{r['junk_dropped_by_kernel']:,} (UDP RcvbufErrors in this namespace: {r['kernel_rcvbuf_errors']})")
    c = r["control"]
    print(f"control port: junk sent {c['sent']:,}, read {c['read']:,}, counted {c['counted']:,}")
    print(f"{'performer':<10} {'kind':<6} {'legit sent':>10} {'legit read':>10} {'junk sent':>10} "
          f"{'junk cntd':>10} {'out sent':>9} {'out recv':>9} {'missing':>8} {'held':>5} {'skip':>5} "
          f"{'drop':>5} {'late':>5} {'p99 ms':>7}")
    for p in r["performers"]:
        ls = "-" if p["legit_sent"] is None else f"{p['legit_sent']:,}"
        print(f"{p['performer']:<10} {p['kind']:<6} {ls:>10} {p['legit_read']:>10,} {p['junk_sent']:>10,} "
              f"{p['junk_counted']:>10,} {p['out_sent']:>9,} {p['out_received']:>9,} {p['out_missing_ticks']:>8,} "
              f"{p['held']:>5} {p['skipped']:>5} {p['dropped']:>5} {p['late']:>5} {p['latency_p99_ms']:>7.1f}")
    print(f"output clock: {r['ticks']:,} ticks, {r['dropped_ticks']:,} dropped (machine too busy), tick start "
          f"lateness p99 {r['tick_late_p99_ms']:.1f} ms")
    print(f"memory: RSS {r['rss_before_mb']:.0f} MB before, {r['rss_after_mb']:.0f} MB after, peak (VmHWM) "
          f"{r['peak_rss_mb']:.0f} MB")
    print(f"log records during the flood: {r['log_records']} {r['log_samples'][:3]}")
    print(f"daemon threads alive at the end: {r['alive']}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--rate", type=float, default=50_000)
    ap.add_argument("--performers", type=int, default=8)
    ap.add_argument("--junk-to", choices=("legit", "separate"), default="legit")
    ap.add_argument("--junk-senders", type=int, default=2)
    ap.add_argument("--restyler", default="standin", help="standin, identity, or a model name/path")
    args = ap.parse_args(argv)
    if args.seconds > 120:
        ap.error("--seconds is capped at 120 (a bench, not a load generator)")
    from machine import describe  # bench/machine.py; imported here because the tests load this file by path

    print("machine: " + describe())
    run_flood(args.seconds, args.rate, args.performers, junk_to=args.junk_to, junk_senders=args.junk_senders,
              restyler=args.restyler)
    return 0


if __name__ == "__main__":
    sys.exit(main())
