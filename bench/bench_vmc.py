"""VMC encode/decode cost and loopback send rate. Prints tables; not a test.

    python bench/bench_vmc.py [--runs 7] [--seconds 1.0]

1. Encode: microseconds per frame (Root + 22 bones + OK + T, random poses), the fast
   path (``vmc_out.FrameEncoder``: template + one float32 scatter) against python-osc's
   builders producing the same bytes (``encode_frame_reference``), bundled and not.
2. Decode: microseconds per frame for the strict OSC decoder alone (``osc_packets.decode``)
   and for ``vmc_parse.VmcParser.feed`` (decoder, frame assembly, Unity -> internal
   conversion), both against python-osc's parser alone (OscBundle/OscMessage + params).
3. Send: frames per second through ``VmcSender.send_frame`` over loopback UDP to 1 and
   4 receivers, each drained by a separate process that counts what arrived, so
   "delivered" shows datagrams the kernel dropped (receive buffer overrun), not only
   what sendto accepted.

Every figure is the median over ``--runs`` runs. The machine is shared: the load average
is printed with the table; rerun when it is high.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import socket
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from machine import describe  # bench/machine.py (scripts run from bench/)

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # a checkout without install

from scipy.spatial.transform import Rotation  # noqa: E402

from stylecast.drivers.vmc.osc_packets import decode  # noqa: E402
from stylecast.drivers.vmc.vmc_parse import VmcParser  # noqa: E402
from stylecast.drivers.vmc.vmc_out import FrameEncoder, VmcSender, encode_frame_reference  # noqa: E402
from stylecast.motion.humanoid import humanoid_skeleton_default  # noqa: E402


def frames(n: int):
    offsets = np.asarray(humanoid_skeleton_default().offsets)
    rots = Rotation.random(n * 22, random_state=0).as_quat().reshape(n, 22, 4)
    roots = np.random.default_rng(0).normal(size=(n, 3)) * 20 + [0, 95, 0]
    return [(roots[i], rots[i], offsets, i / 60) for i in range(n)]


def per_frame_us(fn, work, runs: int) -> float:
    samples = []
    for _ in range(runs):
        t = time.perf_counter()
        for item in work:
            fn(item)
        samples.append((time.perf_counter() - t) / len(work) * 1e6)
    return statistics.median(samples)


def bench_encode(runs: int) -> list[tuple]:
    work = frames(200)
    rows = []
    for bundled in (True, False):
        enc = FrameEncoder(bundled)
        fast = per_frame_us(lambda f: enc.encode(*f), work, runs)
        ref = per_frame_us(lambda f: encode_frame_reference(*f, bundled=bundled), work[:40], runs)
        size = sum(len(d) for d in enc.encode(*work[0]))
        rows.append((f"encode, {'bundled' if bundled else 'unbundled'}", enc.datagrams_per_frame,
                     size, fast, ref, ref / fast))
    return rows


def bench_decode(runs: int) -> list[tuple]:
    from pythonosc.osc_bundle import OscBundle
    from pythonosc.osc_message import OscMessage

    rows = []
    for bundled in (True, False):
        enc = FrameEncoder(bundled)
        stream = [enc.encode(*f) for f in frames(200)]
        parser = VmcParser()

        def ours(datagrams):
            for d in datagrams:
                parser.feed(d, ("127.0.0.1", 1), 0.0)

        def theirs(datagrams):
            for d in datagrams:
                if d[:1] == b"#":
                    [m.params for m in OscBundle(d)]
                else:
                    OscMessage(d).params

        def osc_only(datagrams):
            for d in datagrams:
                decode(d, print)

        label = "bundled" if bundled else "unbundled"
        size = sum(map(len, stream[0]))
        ref = per_frame_us(theirs, stream[:40], runs)
        fast = per_frame_us(osc_only, stream, runs)
        rows.append((f"OSC decode only, {label}", len(stream[0]), size, fast, ref, ref / fast))
        fast = per_frame_us(ours, stream, runs)
        assert parser.counters["frames"] == runs * 200
        rows.append((f"VmcParser.feed, {label}", len(stream[0]), size, fast, ref, ref / fast))
    return rows


def _drain(port_pipe, stop, counts) -> None:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
    s.bind(("127.0.0.1", 0))
    s.settimeout(0.05)
    port_pipe.send(s.getsockname()[1])
    n = 0
    while not stop.is_set():
        try:
            s.recv(65536)
            n += 1
        except socket.timeout:
            pass
    try:
        while True:
            s.recv(65536)
            n += 1
    except socket.timeout:
        counts.put(n)


def bench_send(receivers: int, bundled: bool, seconds: float, runs: int) -> tuple:
    work = frames(120)
    rates, delivered = [], []
    for _ in range(runs):
        ctx = mp.get_context("spawn")
        stop, counts = ctx.Event(), ctx.Queue()
        procs, ports = [], []
        for _ in range(receivers):
            a, b = ctx.Pipe()
            p = ctx.Process(target=_drain, args=(b, stop, counts), daemon=True)
            p.start()
            procs.append(p)
            ports.append(a.recv())
        with VmcSender([("127.0.0.1", port) for port in ports], bundled=bundled) as sender:
            n, t0 = 0, time.perf_counter()
            while time.perf_counter() - t0 < seconds:
                sender.send_frame(*work[n % len(work)])
                n += 1
            elapsed = time.perf_counter() - t0
            sent = sender.datagrams_sent
        stop.set()
        got = sum(counts.get(timeout=10) for _ in procs)
        for p in procs:
            p.join(timeout=5)
        rates.append(n / elapsed)
        delivered.append(got / max(1, sent))
    return (f"send to {receivers} receiver{'s' if receivers > 1 else ''}, "
            f"{'bundled' if bundled else 'unbundled'}", statistics.median(rates),
            statistics.median(rates) * receivers, statistics.median(delivered))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--seconds", type=float, default=1.0)
    args = ap.parse_args()
    from importlib.metadata import version

    print("machine: " + describe(f"python-osc {version('python-osc')}"))
    print(f"median of {args.runs} runs\n")
    print(f"{'':32s} {'datagrams':>9s} {'bytes':>6s} {'stylecast us':>12s} {'python-osc us':>13s} {'speed-up':>8s}")
    for name, dg, size, fast, ref, ratio in bench_encode(args.runs) + bench_decode(args.runs):
        print(f"{name:32s} {dg:9d} {size:6d} {fast:12.1f} {ref:13.1f} {ratio:7.1f}x")
    print(f"\n{'':38s} {'frames/s':>9s} {'frame-sends/s':>13s} {'delivered':>9s}")
    for receivers, bundled in ((1, True), (4, True), (1, False)):
        name, rate, total, ok = bench_send(receivers, bundled, args.seconds, max(1, args.runs // 2))
        print(f"{name:38s} {rate:9.0f} {total:13.0f} {ok:9.1%}")


if __name__ == "__main__":
    main()
