"""Soak: performers replaying Bandai clips through the real daemon on the real clock, for
an hour, memory and latency sampled every minute. Not a test (tests/test_hardening_soak.py
runs a one-minute version).

    nohup python bench/soak.py --minutes 60 --performers 4 > /tmp/soak.log 2>&1 &
    nohup python bench/soak.py --minutes 60 --performers 16 --workers 2 > /tmp/soak.log 2>&1 &

``--workers N`` runs the performers as ``serve --workers N`` does: N processes, each a
whole daemon over a contiguous slice of the performers (its own model, clock, sockets and
receiver), started together; each prints its own samples and the figures are combined at
the end.

Each performer is a ``bvh://...?loop=1`` source (the real driver: BVH read, humanoid
retarget, 60 fps replay) of a different Bandai walk; the daemon sends VMC to one port per
performer, received by a separate process that stamps every frame's arrival on the
system-wide monotonic clock. Sampled on the daemon's own thread (no locking, no
disturbance) every ``--sample-every`` seconds and printed at once:

* RSS and peak RSS (/proc/self/status), open file descriptors, threads;
* per performer latency p50/p99 over the last 10 s (input frame arrival -> its restyled
  frame handed to the socket), the tick start lateness p99, late words;
* the output clock: ticks run + ticks dropped against wall time since the start
  (``clock offset``: ticks the schedule is behind (+) or ahead (-) of 60 x elapsed; the
  schedule is t0 + k/60 by construction, so this must stay within the 2-tick backlog
  whatever the load), and the dropped ticks.

At the end, from the receiving process: frames received vs sent per performer, and the
drift of arrival time against the frames' own /VMC/Ext/T over the run (a least-squares
slope in ppm: an output clock running fast or slow shows here, independently of the
daemon's own bookkeeping).
"""

from __future__ import annotations

import argparse
import gc
import json
import multiprocessing as mp
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))  # also when loaded by path (tests/test_hardening_soak.py)
from machine import describe  # noqa: E402 (bench/machine.py)
from processes import run_together  # noqa: E402 (bench/processes.py)
DATA = REPO.parent / "shared" / "data" / "bandai"
CHECKPOINT = REPO / "models" / "checkpoints" / "normal2exhausted.safetensors"
from stylecast.motion.clock import OUTPUT_FPS as FPS  # noqa: E402 (the one definition)
from stylecast.drivers.vmc.osc_packets import encode_message  # noqa: E402
from stylecast.drivers.vmc.vmc_out import TIME_ADDRESS  # noqa: E402

# The bytes of the OSC message /VMC/Ext/T up to its float argument (the last 4 bytes).
TIME_MESSAGE = encode_message(TIME_ADDRESS, 0.0)[:-4]


def proc_status() -> dict:
    out = {}
    with open("/proc/self/status") as f:
        for line in f:
            key, _, value = line.partition(":")
            if key in ("VmRSS", "VmHWM", "Threads"):
                out[key] = int(value.split()[0])
    out["fds"] = len(os.listdir("/proc/self/fd"))
    return out


def clips(n: int) -> list[str]:
    """``n`` different Bandai clips (walks first), or synthetic ones written to /tmp."""
    folder = DATA / "dataset-2" / "data"
    found = sorted(folder.glob("*_walk_*_001.bvh.gz"))  # one walk per style
    found += sorted(folder.glob("*_walk_*.bvh.gz")) + sorted(folder.glob("*.bvh.gz"))
    unique = list(dict.fromkeys(found))
    if len(unique) >= n:
        return [str(p) for p in unique[:n]]
    from stylecast.motion.bvh import write_bvh
    from tests.test_daemon import walk_clip

    out = []
    for k in range(n):
        path = Path(f"/tmp/stylecast-soak-walk-{k}.bvh")
        write_bvh(walk_clip(600, seed=k), path)
        out.append(str(path))
    return out


def soak_receiver(socks, duration, ready, results) -> None:
    """Receive VMC; keep (tick index, arrival) per frame per port; report at the end.

    Only each bundle's /VMC/Ext/T is decoded, found by its bytes: the full parser
    (VmcParser, tested elsewhere against oscdump) costs ~200 us a frame here, a fifth of a
    core at 16 performers on this 2-core machine, taken from the daemon being measured."""
    import select
    import struct

    ports = [s.getsockname()[1] for s in socks]
    data = {p: [] for p in ports}
    for s in socks:
        s.setblocking(False)
    ready.set()
    parent = os.getppid()
    end = time.monotonic() + duration
    while time.monotonic() < end and os.getppid() == parent:  # a killed soak takes its receiver along
        readable, _, _ = select.select(socks, [], [], 0.1)
        for s in readable:
            i = socks.index(s)
            while True:
                try:
                    d = s.recv(65536)
                except BlockingIOError:
                    break
                now = time.monotonic()
                at = d.find(TIME_MESSAGE)
                if at >= 0:
                    # /VMC/Ext/T is the tick index / 60 as float32: recover the exact index
                    sent = struct.unpack_from(">f", d, at + len(TIME_MESSAGE))[0]
                    data[ports[i]].append((round(sent * FPS), now))
    for s in socks:
        s.close()
    summary = {}
    for p, rows in data.items():
        if len(rows) < 10:
            summary[p] = {"frames": len(rows)}
            continue
        a = np.array(rows)
        ticks = a[:, 0]
        t = ticks / FPS
        offset = a[:, 1] - t  # arrival - schedule (+ t0, a constant)
        # Drift: the schedule's rate against the receiver's clock. Lateness only ever adds
        # to the offset, so fit the low edge: the 5th percentile of each 10 s window.
        edges = np.arange(t[0], t[-1] + 10.0, 10.0)
        which = np.digitize(t, edges)
        win_t = [t[which == w].mean() for w in np.unique(which) if (which == w).sum() >= 100]
        win_o = [np.percentile(offset[which == w], 5) for w in np.unique(which) if (which == w).sum() >= 100]
        slope = np.polyfit(win_t, win_o, 1)[0] if len(win_t) >= 2 else float("nan")
        base = np.percentile(offset, 1)
        summary[p] = {"frames": len(rows), "first_tick": int(ticks[0]), "last_tick": int(ticks[-1]),
                      "missing_ticks": int(ticks[-1] - ticks[0]) + 1 - len(rows),
                      "drift_ppm": float(slope * 1e6),
                      "lateness_p50_ms": float((np.percentile(offset, 50) - base) * 1e3),
                      "lateness_p99_ms": float((np.percentile(offset, 99) - base) * 1e3)}
    results.put(summary)


def soak(minutes: float = 60.0, performers: int = 4, sample_every: float = 60.0, restyler: str = "auto",
         hop: int = 0, log=print, first: int = 0, start=None, worker=(0, 1)) -> dict:
    """``hop`` 0: serve's default settings (the ``--latency default`` preset). ``first``:
    the index of this process's first performer (its clips and names follow on from the
    slices before it); ``start``: a barrier passed once every worker is ready; ``worker``:
    this process's index and the number of processes (as ``serve --workers`` passes it)."""
    from tests.hardening_junk import bind_consecutive

    from stylecast.motion.clock import RealClock
    from stylecast.daemon.config import DaemonConfig
    from stylecast.daemon.engine import Daemon
    from stylecast.daemon.restylers import load_restyler
    from stylecast.drivers.sources import open_source

    if restyler == "auto":
        restyler = str(CHECKPOINT) if CHECKPOINT.exists() else "standin"
    model = load_restyler(restyler)
    paths = clips(first + performers)[first:]
    sources = [open_source(f"bvh://{p}?loop=1&name=p{k}", f"p{k}") for k, p in enumerate(paths, start=first)]
    socks = bind_consecutive(performers)
    base = socks[0].getsockname()[1]
    seconds = minutes * 60.0
    ctx = mp.get_context("fork")
    results, ready = ctx.Queue(), ctx.Event()
    receiver = ctx.Process(target=soak_receiver, args=(socks, seconds + 5.0, ready, results), daemon=True)
    receiver.start()
    for s in socks:
        s.close()
    ready.wait(30)
    stop = threading.Event()
    cfg = DaemonConfig(hop=hop, control="127.0.0.1:0", out=[f"vmc://127.0.0.1:{base}"], status_interval=3600.0)
    daemon = Daemon(cfg, sources, model, RealClock(stop), log_status=False, worker=worker)
    samples = []
    state = {"next": 0.0, "t0": 0.0}
    full_collections = []  # seconds each full (generation 2) garbage collection took

    def time_full_collections(phase, info):
        if info["generation"] == 2:
            if phase == "start":
                state["gc_start"] = time.perf_counter()
            else:
                full_collections.append(time.perf_counter() - state["gc_start"])

    gc.callbacks.append(time_full_collections)

    def sample(now: float) -> None:
        st = proc_status()
        elapsed = now - state["t0"]
        per = [(s.latency.percentile(50) * 1e3, s.latency.percentile(99) * 1e3, s.blender.late_frames)
               for s in daemon.sessions]
        row = {
            "t_s": round(elapsed, 1), "rss_mb": st["VmRSS"] / 1024, "peak_mb": st["VmHWM"] / 1024,
            "threads": st["Threads"], "fds": st["fds"], "ticks": daemon.ticks, "dropped_ticks": daemon.dropped_ticks,
            # ticks run or dropped vs 60 x elapsed (this sample runs inside tick `ticks`)
            "clock_offset_ticks": round(elapsed * FPS - daemon.ticks, 2),
            "tick_late_p99_ms": daemon.tick_lateness.percentile(99) * 1e3,
            "latency_p50_ms": max(p[0] for p in per), "latency_p99_ms": max(p[1] for p in per),
            "late_frames": sum(p[2] for p in per), "delay": daemon.settings.delay,
            "frames_out": sum(s.frames_out for s in daemon.sessions),
            "faults": daemon.worker.faults, "stale_words": getattr(daemon.worker, "stale_words", 0),
            "full_gc": len(full_collections), "full_gc_max_ms": max(full_collections, default=0.0) * 1e3,
            # the model call itself against when its results were ready (queueing and the CPU)
            "model_call_max_ms": max(daemon.worker.call_ms, default=0.0),
            "ready_after_max_ms": daemon.worker.planner.estimate_ms(),
        }
        samples.append(row)
        log(f"[{row['t_s']:7.1f} s] RSS {row['rss_mb']:6.1f} MB (peak {row['peak_mb']:6.1f}) threads "
            f"{row['threads']} fds {row['fds']} | latency p50 {row['latency_p50_ms']:6.1f} p99 "
            f"{row['latency_p99_ms']:6.1f} ms | tick late p99 {row['tick_late_p99_ms']:6.1f} ms | ticks "
            f"{row['ticks']} dropped {row['dropped_ticks']} clock offset {row['clock_offset_ticks']:+.2f} | "
            f"late frames {row['late_frames']} delay {row['delay']} faults {row['faults']} | full GCs "
            f"{row['full_gc']} (max {row['full_gc_max_ms']:.0f} ms) | last 600 jobs: model call max "
            f"{row['model_call_max_ms']:.0f} ms, ready after max {row['ready_after_max_ms']:.0f} ms")

    sampled = daemon.sessions[0].performer

    def tap(frame):
        if frame.performer == sampled:
            now = time.monotonic()
            if now >= state["next"]:
                state["next"] += sample_every
                sample(now)

    daemon.sinks[0].frame_taps.append(tap)
    log(f"soak: {minutes:g} min, {performers} performers ({', '.join(Path(p).name for p in paths)}), "
        f"restyler {daemon.style}, hop {daemon.settings.hop} delay {daemon.settings.delay}, machine {os.cpu_count()} CPUs load {os.getloadavg()[0]:.1f}")
    if start is not None:
        start.wait()
    try:
        daemon.start()
        state["t0"] = daemon.tick_time(0)
        state["next"] = state["t0"]
        t0 = time.monotonic()
        daemon.run(stop, duration=seconds)
        sample(time.monotonic())
        wall = time.monotonic() - t0
    finally:
        daemon.close()
        gc.callbacks.remove(time_full_collections)
    received = results.get(timeout=seconds + 60)
    receiver.join(timeout=10)
    sent = [sinks.vmc.sender.frames_sent for sinks in daemon.sinks]
    out = {"minutes": minutes, "performers": performers, "restyler": daemon.style, "wall_s": wall,
           "samples": samples, "frames_sent": sent,
           "received": {str(p - base): v for p, v in received.items()}}
    warm = next((s for s in samples if s["t_s"] >= min(60.0, seconds / 3)), samples[0])
    end = samples[-1]
    out["summary"] = {
        "rss_after_warmup_mb": warm["rss_mb"], "rss_end_mb": end["rss_mb"],
        "rss_growth_mb": end["rss_mb"] - warm["rss_mb"], "peak_mb": end["peak_mb"],
        "latency_p99_start_ms": warm["latency_p99_ms"], "latency_p99_end_ms": end["latency_p99_ms"],
        "latency_p50_start_ms": warm["latency_p50_ms"], "latency_p50_end_ms": end["latency_p50_ms"],
        "max_abs_clock_offset_ticks": max(abs(s["clock_offset_ticks"]) for s in samples),
        "dropped_ticks": daemon.dropped_ticks, "ticks": daemon.ticks,
        "late_frames": end["late_frames"], "late_frames_after_warmup": end["late_frames"] - warm["late_frames"],
        "delay_start_end": (samples[0]["delay"], end["delay"]),
        "frames_sent": sum(sent), "frames_received": sum(v.get("frames", 0) for v in received.values()),
        "drift_ppm": [round(v.get("drift_ppm", float("nan")), 2) for v in received.values()],
        "threads_start_end": (warm["threads"], end["threads"]), "fds_start_end": (warm["fds"], end["fds"]),
        "full_gc": end["full_gc"], "full_gc_max_ms": end["full_gc_max_ms"],
    }
    s = out["summary"]
    log(f"summary: RSS {s['rss_after_warmup_mb']:.1f} MB after warm-up -> {s['rss_end_mb']:.1f} MB at the end "
        f"(growth {s['rss_growth_mb']:+.1f} MB, peak {s['peak_mb']:.1f}); latency p99 {s['latency_p99_start_ms']:.1f} "
        f"-> {s['latency_p99_end_ms']:.1f} ms (p50 {s['latency_p50_start_ms']:.1f} -> {s['latency_p50_end_ms']:.1f}); "
        f"clock offset max {s['max_abs_clock_offset_ticks']:.2f} ticks; dropped ticks {s['dropped_ticks']} of "
        f"{s['ticks']}; late frames {s['late_frames']} ({s['late_frames_after_warmup']} after warm-up), delay "
        f"{s['delay_start_end'][0]} -> {s['delay_start_end'][1]}; frames sent {s['frames_sent']} received {s['frames_received']}; output drift vs the "
        f"receiver's clock {s['drift_ppm']} ppm; threads {s['threads_start_end']}, fds {s['fds_start_end']}")
    for k, v in sorted(out["received"].items()):
        log(f"  performer {k}: {json.dumps(v)}")
    return out


def _exit_with_parent() -> None:
    """A worker cannot be a daemonic process (it starts its own receiver), so it watches
    its parent instead: a soak stopped with Ctrl-C or kill takes its workers with it."""
    parent = os.getppid()

    def watch():
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()


def _soak_in_process(kwargs, start, conn) -> None:
    """One worker of a ``--workers`` soak: its lines prefixed, its figures sent back."""
    _exit_with_parent()
    tag = f"[p{kwargs['first']}..p{kwargs['first'] + kwargs['performers'] - 1}]"
    conn.send(soak(**kwargs, start=start, log=lambda line: print(f"{tag} {line}", flush=True)))
    conn.close()


def soak_workers(minutes: float, performers: int, workers: int, sample_every: float = 60.0,
                 restyler: str = "auto", log=print) -> dict:
    """The soak as ``serve --workers N`` runs it (daemon/workers.py's ``split``): one whole
    daemon per contiguous slice, all started at once; the summary combined."""
    from stylecast.daemon.workers import split

    slices = split(performers, workers)
    parts = run_together(_soak_in_process, [(dict(minutes=minutes, performers=len(r), sample_every=sample_every,
                                                  restyler=restyler, first=r.start, worker=(w, len(slices))),)
                                            for w, r in enumerate(slices)])
    summaries = [part["summary"] for part in parts]
    added = ("late_frames", "late_frames_after_warmup", "dropped_ticks", "frames_sent", "frames_received")
    combined = {key: sum(s[key] for s in summaries) for key in added}
    combined.update(
        rss_growth_mb=[round(s["rss_growth_mb"], 1) for s in summaries],
        rss_end_mb=[round(s["rss_end_mb"], 1) for s in summaries],
        latency_p99_end_ms=max(s["latency_p99_end_ms"] for s in summaries),
        delay_end=max(s["delay_start_end"][1] for s in summaries),
        max_abs_clock_offset_ticks=max(s["max_abs_clock_offset_ticks"] for s in summaries))
    log(f"combined over {len(slices)} processes: {json.dumps(combined)}")
    return {"workers": parts, "summary": combined}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Soak the daemon: memory, latency and output clock over time.")
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--performers", type=int, default=4)
    ap.add_argument("--workers", type=int, default=1, help="processes, as serve --workers (default 1)")
    ap.add_argument("--sample-every", type=float, default=60.0, help="seconds between samples (default 60)")
    ap.add_argument("--restyler", default="auto", help="auto (shipped model if present, else standin), standin, "
                                                       "identity, or a model name/path")
    ap.add_argument("--json", default="", help="also write every figure to this JSON file")
    args = ap.parse_args(argv)
    log = lambda line: print(line, flush=True)  # noqa: E731
    print(f"machine: {describe()}", flush=True)
    if args.workers > 1:
        result = soak_workers(args.minutes, args.performers, args.workers, args.sample_every, args.restyler, log)
    else:
        result = soak(args.minutes, args.performers, args.sample_every, args.restyler, log=log)
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
