"""Added latency of a live VMC sender by how it stamps its frames (/VMC/Ext/T). Prints a
table; not a test.

    python bench/bench_stamps.py [--runs 3] [--seconds 10] [--model M] [--latency default|low|relaxed]

A sender process sends the shipped walk over loopback at 60 or 30 Hz, paced by its own
clock, to a daemon at serve's default (hop 4, delay 5; ``--latency``: another preset) with
the shipped model. Its stamps:
- ``exact``: frame index / rate from 0, as `bench_daemon.py latency` replays (the baseline);
- ``uptime``: the same from 1234.5 s, sent as OSC's float32: rounded to 0.12 ms, as a real
  sender's uptime is (VirtualMotionCapture and VSeeFace send Unity's ``Time.time``);
- ``clock``: its own clock when it sends, from 1234.5 s, float32: the rounding and its
  scheduling jitter;
- ``epoch``: Unix time, float32: 128 s steps, every frame the same T (timed by arrival:
  ``drivers.vmc.sender_time``; before 2026-11-29 such a performer was never shown).
Latency: the daemon's own figure per output frame (sent - the frame's source time on the
daemon's clock), p50 / p99 / max; median over ``--runs`` runs of each. Holds and skips:
output frames repeated, input frames skipped (the ring absorbing a stall).
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import statistics
import threading
import time

from machine import describe  # bench/machine.py (scripts run from bench/)

STAMPS = {
    "exact": lambda i, rate, elapsed: i / rate,
    "uptime": lambda i, rate, elapsed: 1234.5 + i / rate,
    "clock": lambda i, rate, elapsed: 1234.5 + elapsed,
    "epoch": lambda i, rate, elapsed: time.time(),
}


def send(port: int, rate: float, stamp: str, seconds: float, ready) -> None:
    from stylecast.daemon.clips import bundled_clip
    from stylecast.drivers.bvh.bvh_replay import humanoid_motion
    from stylecast.drivers.vmc.vmc_out import VmcSender
    from stylecast.motion.bvh import read_bvh
    from stylecast.motion.resample import resample

    motion = humanoid_motion(read_bvh(bundled_clip()))
    clip = resample(motion, rate)
    sender = VmcSender([("127.0.0.1", port)])
    ready.wait()
    t0 = time.perf_counter()
    for i in range(int(seconds * rate)):
        # Asleep until 1 ms before its time, then on it: a sender polling all the while took
        # a core of this 2-core machine from the daemon.
        time.sleep(max(0.0, t0 + i / rate - time.perf_counter() - 0.001))
        while time.perf_counter() < t0 + i / rate:
            pass
        j = i % clip.num_frames
        # /VMC/Ext/T goes out as a float32, which rounds the larger stamps
        sender.send_frame(clip.root_positions[j], clip.rotations[j], motion.skeleton.offsets,
                          STAMPS[stamp](i, rate, time.perf_counter() - t0))
    sender.close()


def one_run(rate: float, stamp: str, seconds: float, model, latency: str) -> dict:
    from stylecast.daemon.config import DaemonConfig
    from stylecast.daemon.engine import Daemon
    from stylecast.drivers.sources import open_source
    from stylecast.motion.clock import RealClock

    source = open_source("vmc://127.0.0.1:0?input=bones", "p0")
    ready = mp.get_context("spawn").Event()
    sender = mp.get_context("spawn").Process(target=send, args=(source.receiver.address[1], rate, stamp,
                                                                seconds + 2.0, ready))
    sender.start()
    daemon = Daemon(DaemonConfig(latency=latency, control="off"), [source], model, RealClock(), log_status=False)
    stop = threading.Event()
    try:
        daemon.start()
        ready.set()
        threading.Timer(seconds, stop.set).start()
        daemon.run(stop)
        s = daemon.sessions[0]
        return {"p50": 1e3 * s.latency.percentile(50), "p99": 1e3 * s.latency.percentile(99),
                "max": 1e3 * s.latency.percentile(100), "held": s.held, "skipped": s.skipped,
                "late": s.blender.late_frames, "delay": s.settings.delay,
                "locked": getattr(s.resampler, "locked", False)}  # the code before had no lock
    finally:
        daemon.close()
        sender.join()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--model", default=None, help="serve --model (default: the shipped one)")
    ap.add_argument("--latency", default="default", help="serve --latency preset (default: default)")
    args = ap.parse_args()
    from stylecast.daemon.latency import LATENCY_PRESETS
    from stylecast.daemon.restylers import load_restyler

    if args.latency not in LATENCY_PRESETS:
        ap.error(f"--latency must be one of {', '.join(LATENCY_PRESETS)}, got {args.latency!r}")
    preset = LATENCY_PRESETS[args.latency]

    model = load_restyler(args.model or "normal2exhausted")
    print("machine: " + describe())
    print(f"--latency {args.latency}: {preset.about}; model {args.model or 'normal2exhausted'}, "
          f"{args.seconds:g} s a run, median of {args.runs} runs")
    print("| rate | stamps | latency p50 ms | p99 ms | max ms | holds | skips | late | final delay | locked |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for rate in (60.0, 30.0):
        for stamp in STAMPS:
            runs = [one_run(rate, stamp, args.seconds, model, args.latency) for _ in range(args.runs)]
            med = {k: statistics.median(r[k] for r in runs) for k in ("p50", "p99", "max")}
            print(f"| {rate:g} Hz | {stamp} | {med['p50']:.1f} | {med['p99']:.1f} | {med['max']:.1f} | "
                  f"{sum(r['held'] for r in runs)} | {sum(r['skipped'] for r in runs)} | "
                  f"{sum(r['late'] for r in runs)} | {'/'.join(str(r['delay']) for r in runs)} | "
                  f"{sum(r['locked'] for r in runs)}/{len(runs)} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
