"""Full sweep of humanoid retargeting over every shared Bandai clip.

For each clip: forward kinematics of the humanoid motion (canonical rotations on the
canonical skeleton with the clip's bone lengths) against the source's own world joint
positions; the twist conventions calibrated from the motion; the time per frame.
Prints a table (maximum and percentiles of the position error, conventions found).

    python bench/bench_retarget.py [--limit N]
"""

from __future__ import annotations

import argparse
import collections
import time
from pathlib import Path

import numpy as np

from machine import describe  # bench/machine.py (scripts run from bench/)

from stylecast.motion import forward_kinematics
from stylecast.motion.bvh import read_bvh
from stylecast.motion.humanoid import Retarget

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bandai"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--limit", type=int, default=0, help="only the first N clips (0: all)")
    args = parser.parse_args()
    files = sorted((DATA / "dataset-2" / "data").glob("*.bvh.gz")) + sorted((DATA / "dataset-1" / "data").glob("*.bvh"))
    if args.limit:
        files = files[:: max(1, len(files) // args.limit)][: args.limit]
    errors, conventions, frames, seconds = [], collections.Counter(), 0, 0.0
    worst = ("", 0.0)
    for path in files:
        clip = read_bvh(path)
        start = time.perf_counter()
        retarget = Retarget.for_clip(clip)
        human = retarget.to_humanoid(clip)
        seconds += time.perf_counter() - start
        frames += clip.num_frames
        src, _ = forward_kinematics(clip)
        hum, _ = forward_kinematics(human)
        err = max(float(np.abs(hum[:, h] - src[:, s]).max()) for h, s in enumerate(retarget.bone_source) if s >= 0)
        errors.append(err)
        if err > worst[1]:
            worst = (path.name, err)
        conventions[tuple(sorted(retarget.twists.items()))] += 1
    e = np.array(errors) * 10.0  # cm -> mm
    print("machine: " + describe())
    print(f"clips: {len(files)}  frames: {frames}  retarget: {frames / seconds:,.0f} frames/s (calibration included)")
    print("| FK error vs source (mm) | value |\n|---|---|")
    for name, value in (("max", e.max()), ("p99", np.percentile(e, 99)), ("median", np.median(e))):
        print(f"| {name} | {value:.2e} |")
    print(f"worst clip: {worst[0]} ({worst[1] * 10:.2e} mm)")
    print("twist conventions found (clips):")
    for key, count in conventions.most_common():
        print(f"  {count:5d}  {dict(key)}")


if __name__ == "__main__":
    main()
