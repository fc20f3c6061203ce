"""Tracker solver: accuracy on Bandai clips and throughput per performer on one core.

    python bench/bench_solver.py                 # every 10th dataset-2 clip, all conditions
    python bench/bench_solver.py --step 1        # the full sweep (about 2,400 clips)
    python bench/bench_solver.py --dataset dataset-1 --step 1
    python bench/bench_solver.py --throughput-only

Accuracy: each clip is retargeted to the humanoid, emulated as trackers (straps jittered
by 1.5 cm / 5 degrees), calibrated on its first second (30 frames) with a prior skeleton
12 % too small and 5 % wrong per bone (the solver must learn the proportions), then solved;
world joint positions are compared with the clip's own humanoid forward kinematics on
every later frame, over the bones the source has (Bandai rigs have no UpperChest).
dataset-2 is the held-out set: the solver's few constants were chosen on dataset-1.

Throughput: frames per second for one performer, single-threaded BLAS, on a long
recording: ``solve_batch`` (vectorised over frames) with and without dropouts, and the
per-frame ``solve`` path the live source uses.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from stylecast.drivers.emulator import emulate_trackers, load_humanoid  # noqa: E402
from stylecast.drivers.solver import TrackerSolver, calibrate_known_pose  # noqa: E402
from stylecast.motion import Clip, forward_kinematics  # noqa: E402
from stylecast.motion.humanoid import HUMANOID_BONES  # noqa: E402

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bandai"
CALIB = 30
CONDITIONS = {  # name: (points, emulator options)
    "10 points": (10, {}),
    "10 points, 5 mm noise": (10, {"noise_mm": 5.0}),
    "6 points": (6, {}),
    "6 points, 5 mm noise": (6, {"noise_mm": 5.0}),
    "10 points, 5 % dropouts": (10, {"drop": 0.05}),
}


def clip_errors(motion: Clip, points: int, seed: int, **emulate) -> np.ndarray:
    rng = np.random.default_rng(seed)
    prior = motion.skeleton.with_offsets(motion.skeleton.offsets * 0.88
                                         * rng.uniform(0.95, 1.05, (len(HUMANOID_BONES), 1)))
    rec = emulate_trackers(motion, points, seed=seed, mount_jitter_cm=1.5, mount_jitter_deg=5, **emulate)
    clean = emulate_trackers(motion, points, seed=seed, mount_jitter_cm=1.5, mount_jitter_deg=5,
                             noise_mm=emulate.get("noise_mm", 0.0))
    cal = calibrate_known_pose(clean.arrays(0, CALIB), motion.slice(0, CALIB).replace(skeleton=prior), rec.roles)
    root, local = TrackerSolver(cal).solve_batch(*rec.arrays(CALIB))
    est, _ = forward_kinematics(Clip(cal.skeleton, local, root, motion.fps))
    ref, _ = forward_kinematics(motion.slice(CALIB, motion.num_frames))
    return np.linalg.norm(est - ref, axis=-1)


def accuracy(files: list[Path], out) -> None:
    keep = [j for j, b in enumerate(HUMANOID_BONES) if b != "UpperChest"]
    errs = {name: [] for name in CONDITIONS}
    t0 = time.perf_counter()
    used = 0
    for k, path in enumerate(files):
        motion = load_humanoid(path)
        if motion.num_frames < CALIB + 10:
            continue
        used += 1
        for name, (points, opts) in CONDITIONS.items():
            errs[name].append(clip_errors(motion, points, seed=k, **opts)[:, keep])
        if (k + 1) % 50 == 0:
            print(f"  {k + 1}/{len(files)} clips ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    frames = sum(len(e) for e in errs["10 points"])
    print(f"\naccuracy: {used} clips, {frames} solved frames, {len(keep)} bones per frame (cm)\n", file=out)
    print(f"{'condition':<26} {'mean':>6} {'p95':>6} {'max':>6}", file=out)
    for name, e in errs.items():
        a = np.concatenate([x.ravel() for x in e])
        print(f"{name:<26} {a.mean():6.2f} {np.percentile(a, 95):6.2f} {a.max():6.1f}", file=out)
    print("\nmean error per bone (cm)", file=out)
    print(f"{'bone':<15}" + "".join(f"{n.replace(' points', 'p').replace(', ', ' ')[:12]:>13}" for n in errs),
          file=out)
    per = {n: np.concatenate(e).mean(0) for n, e in errs.items()}
    for i, j in enumerate(keep):
        print(f"{HUMANOID_BONES[j]:<15}" + "".join(f"{per[n][i]:13.2f}" for n in errs), file=out)


def throughput(path: Path | None, out) -> None:
    if path is not None:
        motion = load_humanoid(path)
    else:  # no data: any smooth motion does for timing
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        from tests.test_solver import body_motion

        motion = body_motion(frames=600)
    reps = max(1, 20000 // motion.num_frames)
    long = motion.replace(rotations=np.concatenate([motion.rotations] * reps),
                          root_positions=np.concatenate([motion.root_positions] * reps))
    rec = emulate_trackers(long, 10, noise_mm=1.0)
    cal = calibrate_known_pose(rec.arrays(0, CALIB), long.slice(0, CALIB), rec.roles)
    solver = TrackerSolver(cal)
    T = len(rec)

    def rate(fn, n):
        # CPU time of this process: frames per second of one core, even when other work
        # shares the machine (wall-clock rates under load would understate it).
        best = 0.0
        for _ in range(3):
            t = time.process_time()
            fn()
            best = max(best, n / max(time.process_time() - t, 1e-9))
        return best

    arrays = rec.arrays()
    batch = rate(lambda: solver.solve_batch(*arrays), T)
    dropped = emulate_trackers(long, 10, noise_mm=1.0, drop=0.05, seed=1)
    darrays = dropped.arrays()
    batch_drop = rate(lambda: solver.solve_batch(*darrays), T)
    n = 600
    poses = [rec.poses(i) for i in range(n)]
    frame = rate(lambda: [solver.solve(p) for p in poses], n)
    dposes = [dropped.poses(i) for i in range(n)]
    solver.reset()
    frame_drop = rate(lambda: [solver.solve(p) for p in dposes], n)
    solver.reset()
    pairs = [poses[i:i + 2] for i in range(0, n, 2)]
    live2 = rate(lambda: [solver.solve_live(p) for p in pairs], n)
    rec6 = emulate_trackers(long, 6)
    solver6 = TrackerSolver(calibrate_known_pose(rec6.arrays(0, CALIB), long.slice(0, CALIB), rec6.roles))
    a6 = rec6.arrays()
    batch6 = rate(lambda: solver6.solve_batch(*a6), T)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"\nthroughput: one performer, one thread, {T} frames, frames per CPU-second (load average "
          f"{load:.1f} on {os.cpu_count()} cores while measuring)\n", file=out)
    print(f"{'path':<44} {'frames/s':>10}", file=out)
    print(f"{'solve_batch, 10 points':<44} {batch:10.0f}", file=out)
    print(f"{'solve_batch, 6 points':<44} {batch6:10.0f}", file=out)
    print(f"{'solve_batch, 10 points, 5 % dropouts':<44} {batch_drop:10.0f}", file=out)
    print(f"{'solve (per frame, live path), 10 points':<44} {frame:10.0f}", file=out)
    print(f"{'solve (per frame), 10 points, 5 % dropouts':<44} {frame_drop:10.0f}", file=out)
    print(f"{'solve_live, 2 frames per call (120 Hz, 60 Hz poll)':<44} {live2:10.0f}", file=out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", default="dataset-2", choices=("dataset-1", "dataset-2"))
    ap.add_argument("--step", type=int, default=10, help="take every STEP-th clip (1: all)")
    ap.add_argument("--throughput-only", action="store_true")
    args = ap.parse_args(argv)
    files = []
    if DATA.is_dir():
        files = sorted((DATA / args.dataset / "data").glob("*.bvh*"))[::max(1, args.step)]
    if not args.throughput_only:
        if not files:
            print(f"no Bandai data at {DATA}; accuracy skipped", file=sys.stderr)
        else:
            accuracy(files, sys.stdout)
    throughput(files[0] if files else None, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
