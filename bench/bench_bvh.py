"""Benchmark the BVH reader on the shared Bandai clips: MB/s of uncompressed text and frames/s.

    python bench/bench_bvh.py [--files 200] [--repeats 5] [--data PATH]

Files are read and gunzipped into memory first; only parsing is timed. Each case runs
--repeats times and the table shows the median (wall clock, and CPU time of this process,
which is the fairer number on a machine shared with other jobs). Cases:

* parse_bvh      the whole reader: hierarchy, MOTION numbers, Euler -> quaternions, Clip
* MOTION numbers only the vectorised number parser with its row checks (bvh._motion_values)
* np.array(split) the obvious numpy baseline on the MOTION text, for comparison
* "one file"     the same clips joined into one long BVH, which shows the per-file overhead
"""

from __future__ import annotations

import argparse
import gzip
import random
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from machine import describe  # bench/machine.py (scripts run from bench/)

from stylecast.motion import bvh

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bandai"


def load(paths: list[Path]) -> list[bytes]:
    texts = []
    for path in paths:
        raw = path.read_bytes()
        texts.append(gzip.decompress(raw) if raw[:2] == b"\x1f\x8b" else raw)
    return texts


def motion_start(text: bytes) -> int:
    at = text.index(b"Frame Time")
    return text.index(b"\n", at) + 1


def joined(texts: list[bytes]) -> bytes:
    """One BVH holding every frame of ``texts`` (which must share a skeleton)."""
    bodies = [t[motion_start(t):] for t in texts]
    frames = sum(b.count(b"\n") for b in bodies)
    head = texts[0][:texts[0].index(b"MOTION")]
    return head + b"MOTION\nFrames: %d\nFrame Time: 0.0333333\n" % frames + b"".join(bodies)


def cases(texts: list[bytes]) -> dict:
    """name -> (function that parses everything once, frames parsed per call)."""
    clips = [bvh.parse_bvh(t, "warm-up") for t in texts]
    frames = sum(c.num_frames for c in clips)
    layout = [(motion_start(t), c.num_frames, bvh._layout(c.skeleton.channels, tuple(range(len(c.skeleton)))).num_channels)
              for t, c in zip(texts, clips)]
    bodies = [t[motion_start(t):] for t in texts]
    return {
        "parse_bvh": (lambda: [bvh.parse_bvh(t, "bench") for t in texts], frames),
        "MOTION numbers only": (lambda: [bvh._motion_values(t, s, 1, f, c, "bench") for t, (s, f, c) in zip(texts, layout)], frames),
        "np.array(split) baseline": (lambda: [np.array(b.split(), dtype=np.float64) for b in bodies], frames),
    }


def measure(fn, repeats: int) -> tuple[float, float]:
    walls, cpus = [], []
    for _ in range(repeats):
        w, c = time.perf_counter(), time.process_time()
        fn()
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return statistics.median(walls), statistics.median(cpus)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--files", type=int, default=200, help="clips sampled from each dataset (default 200)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the bandai folder holding dataset-1/ and dataset-2/")
    args = parser.parse_args()
    sets = {"dataset-2 (.bvh.gz)": sorted((args.data / "dataset-2" / "data").glob("*.bvh.gz")),
            "dataset-1 (.bvh)": sorted((args.data / "dataset-1" / "data").glob("*.bvh"))}
    if not any(sets.values()):
        print(f"no Bandai BVH files under {args.data}", file=sys.stderr)
        return 1

    print("machine: " + describe())
    print(f"median of {args.repeats} runs; text is uncompressed BVH already in memory\n")
    print(f"{'clips':40s} {'case':26s} {'MB':>7s} {'MB/s wall':>10s} {'MB/s CPU':>9s} {'frames/s CPU':>13s}")
    for name, paths in sets.items():
        sample = sorted(random.Random(0).sample(paths, min(args.files, len(paths))))
        texts = load(sample)
        groups = {f"{name}, {len(texts)} files": texts, f"{name}, same as one file": [joined(texts)]}
        for label, group in groups.items():
            size = sum(map(len, group)) / 1e6
            for case, (fn, frames) in cases(group).items():
                wall, cpu = measure(fn, args.repeats)
                print(f"{label:40s} {case:26s} {size:7.1f} {size / wall:10.1f} {size / cpu:9.1f} {frames / cpu:13,.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
