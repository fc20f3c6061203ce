"""Tracker solver: accuracy on Bandai clips and throughput per performer on one core.

    python bench/bench_solver.py                 # every 10th dataset-2 clip, all conditions
    python bench/bench_solver.py --step 1        # the full sweep (about 2,400 clips)
    python bench/bench_solver.py --dataset dataset-1 --step 1
    python bench/bench_solver.py --throughput-only [--runs 9] [--baseline 1912b04]

Accuracy: each clip is retargeted to the humanoid, emulated as trackers (straps jittered
by 1.5 cm / 5 degrees), calibrated on its first second (30 frames) with a prior skeleton
12 % too small and 5 % wrong per bone (the solver must learn the proportions), then solved;
world joint positions are compared with the clip's own humanoid forward kinematics on
every later frame, over the bones the source has (Bandai rigs have no UpperChest).
dataset-2 is the held-out set: the solver's few constants were chosen on dataset-1.

Throughput: frames per second for one performer, single-threaded BLAS, on a long
recording: the per-frame ``solve`` path the live source uses (the issue's goal: 10,000
per performer on one core) and ``solve_batch`` (vectorised over frames), each with and
without dropouts. Rates are frames per CPU-second of this process (``time.process_time``),
the median of several runs, so other work on the machine costs wall time but not the
figure; the machine and its load average are printed with them, as shared machines still
slow CPU time (caches, SMT siblings: on a busy two-core machine the same code measured
anywhere from 5,000 to 10,500 frames/s). ``--baseline REV`` times the solver of an older
revision in the same runs, so the before/after ratio holds whatever the load.

    python bench/bench_solver.py --throughput-only --baseline 1912b04
"""

from __future__ import annotations

from machine import describe  # bench/machine.py (scripts run from bench/)

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from stylecast.drivers.trackers.emulator import emulate_trackers, load_humanoid  # noqa: E402
from stylecast.drivers.trackers.solver import TrackerSolver, calibrate_known_pose  # noqa: E402
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


def _baseline(rev: str):
    """drivers/trackers/solver.py as it was at git revision ``rev``, imported beside the current one
    (its relative imports resolve to today's drivers package), for before/after figures
    from the same run: on a shared machine only those compare."""
    import importlib.util
    import subprocess
    import tempfile

    repo = Path(__file__).resolve().parents[1]
    src = subprocess.run(["git", "-C", str(repo), "show", f"{rev}:drivers/trackers/solver.py"], capture_output=True,
                         text=True, check=True).stdout
    with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as f:
        f.write(src)
    name = "stylecast.drivers._solver_baseline"
    spec = importlib.util.spec_from_file_location(name, f.name)
    module = importlib.util.module_from_spec(spec)
    module.__package__ = "stylecast.drivers"
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    finally:
        os.unlink(f.name)
    return module


def throughput(path: Path | None, out, runs: int = 5, baseline: str | None = None) -> None:
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
    solver = TrackerSolver(calibrate_known_pose(rec.arrays(0, CALIB), long.slice(0, CALIB), rec.roles))
    rec6 = emulate_trackers(long, 6)
    solver6 = TrackerSolver(calibrate_known_pose(rec6.arrays(0, CALIB), long.slice(0, CALIB), rec6.roles))
    dropped = emulate_trackers(long, 10, noise_mm=1.0, drop=0.05, seed=1)
    T, n = len(rec), 2000
    poses = [rec.poses(i) for i in range(n)]
    dposes = [dropped.poses(i) for i in range(n)]
    poses6 = [rec6.poses(i) for i in range(n)]
    pairs = [poses[i:i + 2] for i in range(0, n, 2)]
    arrays, darrays, a6 = rec.arrays(), dropped.arrays(), rec6.arrays()
    cases = [  # name, work, frames, state to clear first
        ("solve (per frame, live path), 10 points", lambda: [solver.solve(p) for p in poses], n, solver.reset),
        ("solve (per frame), 6 points", lambda: [solver6.solve(p) for p in poses6], n, solver6.reset),
        ("solve (per frame), 10 points, 5 % dropouts", lambda: [solver.solve(p) for p in dposes], n, solver.reset),
        ("solve_live, 2 frames per call (120 Hz, 60 Hz poll)", lambda: [solver.solve_live(p) for p in pairs], n,
         solver.reset),
        ("solve_batch, 10 points", lambda: solver.solve_batch(*arrays), T, None),
        ("solve_batch, 6 points", lambda: solver6.solve_batch(*a6), T, None),
        ("solve_batch, 10 points, 5 % dropouts", lambda: solver.solve_batch(*darrays), T, None),
    ]
    if baseline:
        old = _baseline(baseline)
        before = old.TrackerSolver(old.calibrate_known_pose(rec.arrays(0, CALIB), long.slice(0, CALIB), rec.roles))
        cases += [
            (f"before ({baseline}): solve, 10 points", lambda: [before.solve(p) for p in poses[:n // 4]], n // 4,
             before.reset),
            (f"before ({baseline}): solve_batch, 10 points", lambda: before.solve_batch(*arrays), T, None),
        ]
    # CPU time of this process: frames per second of one core, even when other work shares
    # the machine (wall-clock rates under load would understate it). The cases take turns
    # within each run, so a spell of heavier load touches all of them alike, and each
    # figure is the median of its runs.
    load0 = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    rates: dict[str, list[float]] = {name: [] for name, *_ in cases}
    for _ in range(runs):
        for name, work, frames, reset in cases:
            if reset is not None:
                reset()
            t = time.process_time()
            work()
            rates[name].append(frames / max(time.process_time() - t, 1e-9))
    load1 = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"\nthroughput: one performer, one thread, frames per CPU-second, median of {runs} runs "
          f"({n} live frames; {T} frames per batch)", file=out)
    print(f"machine: {describe()}; load average {load0:.1f} -> {load1:.1f} while measuring\n", file=out)
    print(f"{'path':<52} {'frames/s':>10} {'us/frame':>9}", file=out)
    for name, r in rates.items():
        rate = float(np.median(r))
        print(f"{name:<52} {rate:10.0f} {1e6 / rate:9.1f}", file=out)
    if baseline:
        for label, now, then in (("solve, per frame", cases[0][0], cases[-2][0]),
                                 ("solve_batch", cases[4][0], cases[-1][0])):
            ratio = np.median(np.array(rates[now]) / np.array(rates[then]))
            print(f"speed-up since {baseline}, {label}, 10 points: x{ratio:.1f} (median of the per-run ratios)",
                  file=out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", default="dataset-2", choices=("dataset-1", "dataset-2"))
    ap.add_argument("--step", type=int, default=10, help="take every STEP-th clip (1: all)")
    ap.add_argument("--throughput-only", action="store_true")
    ap.add_argument("--runs", type=int, default=5, help="timed runs per throughput figure (median reported)")
    ap.add_argument("--baseline", metavar="REV", help="also time drivers/trackers/solver.py at git revision REV (e.g. "
                    "1912b04, before the per-frame rewrite) in the same runs")
    args = ap.parse_args(argv)
    files = []
    if DATA.is_dir():
        files = sorted((DATA / args.dataset / "data").glob("*.bvh*"))[::max(1, args.step)]
    if not args.throughput_only:
        if not files:
            print(f"no Bandai data at {DATA}; accuracy skipped", file=sys.stderr)
        else:
            accuracy(files, sys.stdout)
    throughput(files[0] if files else None, sys.stdout, max(1, args.runs), args.baseline)
    return 0


if __name__ == "__main__":
    sys.exit(main())
