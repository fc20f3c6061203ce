"""Headless viewer speed: frames per second for 1 and 8 performers (input + restyled pairs
count as two), through EGL on whatever renderer this machine has (llvmpipe without a GPU).

Each run renders for ``--seconds`` with poses changing every frame (so forward kinematics
and the instance upload are paid every frame, as in a live stream); the table shows the
median over ``--runs`` runs. "render" waits for the GL to finish each frame (what a window
would show); "+ readback" also reads the pixels back (what --frames pays before PNG
encoding). The goal from issue 6: >= 60 fps for 8 performers with the software renderer.

    python bench/bench_viewer.py [--runs 5] [--seconds 1.5] [--width 1280 --height 720]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from machine import describe  # bench/machine.py (scripts run from bench/)
from scipy.spatial.transform import Rotation

from stylecast.motion.humanoid import HUMANOID_BONES
from stylecast.viewer.app import Viewer
from stylecast.viewer.context import create_headless_context


def poses(n: int, k: int, rng: np.random.Generator) -> np.ndarray:
    """n performers' poses at frame k: every bone swinging a little, differently per performer."""
    phase = rng.uniform(0, 2 * np.pi, (n, len(HUMANOID_BONES), 3))
    angles = 25.0 * np.sin(k / 20.0 + phase)
    return Rotation.from_euler("xyz", angles.reshape(-1, 3), degrees=True).as_quat().reshape(n, -1, 4)


def run_once(ctx, performers: int, samples: int, readback: bool, seconds: float, size) -> tuple[float, float]:
    """(frames per second, CPU ms per frame of the whole process: Python, the GL driver
    and llvmpipe's rasteriser threads). On a shared machine the second figure is the
    steadier one: it does not grow when other processes take the cores."""
    clock_start = time.monotonic()
    v = Viewer(ctx, size=size, samples=samples)
    rng = np.random.default_rng(0)
    roles = ["restyled", "input"]
    idents = [(roles[i % 2], f"performer-{i // 2}") for i in range(performers)]
    root = np.array([0.0, 95.0, 0.0])

    def feed(k: int) -> None:
        now = time.monotonic()
        for (role, ident), q in zip(idents, poses(performers, k, rng)):
            v.table.update_pose(role, ident, root, q, now - clock_start, now)

    feed(0)
    v.render_offscreen()
    ctx.finish()
    frames = 0
    start, cpu_start = time.perf_counter(), time.process_time()
    while time.perf_counter() - start < seconds:
        feed(frames)  # in the viewer the listener threads do this, concurrently
        v.render_offscreen()
        if readback:
            v.read_pixels()
        else:
            ctx.finish()
        frames += 1
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu_start
    return frames / elapsed, cpu / frames * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=1.5)
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    args = ap.parse_args()
    size = (args.width, args.height)
    ctx = create_headless_context()
    print(f"machine:  {describe()}")
    print(f"renderer: {ctx.info['GL_RENDERER']} / {ctx.info['GL_VERSION']}")
    print(f"image:    {size[0]}x{size[1]}, median of {args.runs} runs of {args.seconds:.1f} s each")
    if hasattr(os, "getloadavg"):  # a shared machine: say how busy it was
        print("load:     %.1f %.1f %.1f (1, 5, 15 min averages at start)" % os.getloadavg())
    print()
    print("| performers | MSAA | render fps | + readback fps | CPU ms/frame (all threads) |")
    print("|-----------:|-----:|-----------:|---------------:|---------------------------:|")
    for samples in (0, 4):
        for n in (1, 8):
            render = [run_once(ctx, n, samples, False, args.seconds, size) for _ in range(args.runs)]
            read = [run_once(ctx, n, samples, True, args.seconds, size) for _ in range(args.runs)]
            fps = statistics.median(r[0] for r in render)
            fps_read = statistics.median(r[0] for r in read)
            cpu = statistics.median(r[1] for r in render)
            print(f"| {n:10d} | {samples:4d} | {fps:10.1f} | {fps_read:14.1f} | {cpu:26.2f} |", flush=True)
    assert ctx.error == "GL_NO_ERROR", ctx.error


if __name__ == "__main__":
    main()
