"""Capacity runs of the daemon (``bench_daemon.py capacity`` and ``capacity-workers``): N
performers, each to its own port, drained by a receiver process, N growing until a run drops
an output tick or shows late words; over one process per core as ``serve --workers`` runs
it, against the previous releases' settings in the same run."""

from __future__ import annotations

import time

import numpy as np

from daemon_rig import Receiver, base_motion, free_ports, make_daemon, restyler, table  # bench/daemon_rig.py
from processes import run_together  # bench/processes.py


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
    return dict(n=n, dropped=d.dropped_ticks, late=late, delay=d.settings.delay, p99=p99,
                tick99=d.tick_lateness.percentile(99) * 1e3, cpu=cpu, wall=wall, received=received,
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
