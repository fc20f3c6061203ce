"""Model benchmarks: generator cost per word and per batch of 64, the Restyler's full
batch call (numpy in and out), and offline `restyle` throughput. Prints a table; not a test.

    python bench/bench_models.py [--model PATH|NAME] [--repeats 30] [--device cpu|cuda[:N]] [--threads 1]

Everything runs on ONE torch thread (torch.set_num_threads(1)), the live budget's setting:
one word <= 2 ms, 64 words <= 40 ms; ``--threads N`` gives torch more. Times are medians
over --repeats runs after warm-up. The machine is shared, so the load average is printed
with the results. ``--device cuda`` puts the model (and the representation work) on the
GPU; run it beside ``--device cpu`` on the same machine for the baseline (issue 12).
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import threading
import time
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from machine import describe  # bench/machine.py (scripts run from bench/)

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "bandai" / "dataset-2" / "data"


def median_ms(fn, repeats: int, warmup: int = 5, cpu_clock=time.process_time) -> tuple[float, float]:
    """Median wall-clock and median CPU milliseconds per call (the process's, or the
    calling thread's with ``cpu_clock=time.thread_time``). On a shared, loaded machine the
    CPU time is what the call itself costs; wall time includes waiting for a core."""
    for _ in range(warmup):
        fn()
    wall, cpu = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), cpu_clock()
        fn()
        wall.append(time.perf_counter() - t)
        cpu.append(cpu_clock() - c)
    return 1000 * statistics.median(wall), 1000 * statistics.median(cpu)


@contextlib.contextmanager
def busy_python_thread(switch_interval: float):
    """A thread running pure Python beside the caller (as the daemon's output loop does
    beside its model thread), with the GIL's switch interval set for the duration."""
    before = sys.getswitchinterval()
    sys.setswitchinterval(switch_interval)
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            sum(range(100))

    thread = threading.Thread(target=spin, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()
        sys.setswitchinterval(before)


def throughput(fn, frames: int) -> tuple[float, float]:
    t, c = time.perf_counter(), time.process_time()
    fn()
    return frames / (time.perf_counter() - t), frames / max(time.process_time() - c, 1e-9)


def load_restyler(name, device="cpu"):
    from stylecast.models.restyler import Restyler
    from stylecast.motion.errors import UserError

    try:
        return Restyler.load(name, device=device), "trained"
    except UserError as exc:
        # No shipped model yet: an untrained one of the same size costs the same.
        from stylecast.models import checkpoint as ckpt
        from stylecast.models.train import Trainer, TrainConfig, model_metadata
        from stylecast.motion import rotations as rot

        print(f"({exc} -- timing an untrained model of the default size)")
        words = rot.identity((4, 60, 22))
        tr = Trainer(TrainConfig(), words, words, device="cpu")
        path = Path("/tmp/bench_models_untrained.safetensors")
        ckpt.save_checkpoint(path, tr.model_tensors(True), model_metadata(tr.cfg, tr.rep), sidecar=False)
        return Restyler.load(path, device=device), "untrained"


class UnfoldConv1d(torch.nn.Conv1d):
    """The previous release's batch-invariant convolution, kept here as a baseline: every
    frame's taps unfolded into a copied (B * T', C * k) matrix, one product."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        (k,), (stride,), (pad,) = self.kernel_size, self.stride, self.padding
        if pad:
            x = F.pad(x, (pad, pad), mode="replicate" if self.padding_mode == "replicate" else "constant")
        taps = x.unfold(2, k, stride)  # (B, Cin, T', k)
        b, cin, frames, _ = taps.shape
        rows = taps.permute(0, 2, 1, 3).reshape(b * frames, cin * k)
        out = torch.addmm(self.bias, rows, self.weight.reshape(self.out_channels, cin * k).t())
        return out.reshape(b, frames, self.out_channels).transpose(1, 2)


def previous_inference_form(generator):
    """A copy of ``generator`` with the previous release's convolution and the native
    instance norm (its layers' forms before this release)."""
    from stylecast.models.conditioning import RowInstanceNorm1d
    from stylecast.models.networks import RowConv1d, copy_with_forms

    return copy_with_forms(generator, {RowConv1d: UnfoldConv1d, RowInstanceNorm1d: torch.nn.InstanceNorm1d})


def random_words(n: int) -> np.ndarray:
    """``n`` smooth random words (a random walk of Euler angles per joint), one hemisphere."""
    from stylecast.motion import rotations as rot

    rng = np.random.default_rng(0)
    angles = np.cumsum(rng.normal(0, 1.0, (n, 60, 22, 3)), axis=1) + rng.normal(0, 20, (n, 1, 22, 3))
    return rot.canonical_hemisphere(rot.from_euler(angles, "XZY"), axis=1)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--device", default="cpu", help="where the model runs: cpu, cuda, cuda:N (default cpu)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads (default 1, the daemon's setting)")
    ap.add_argument("--batches", default="1,64,4096", help="restyle_words batch sizes for the throughput table")
    args = ap.parse_args()

    torch.set_num_threads(args.threads)
    from stylecast.models.device import pick_device
    from stylecast.motion.errors import UserError

    try:
        pick_device(args.device)
    except UserError as exc:
        print(f"bench_models: {exc}", file=sys.stderr)
        return 2
    from stylecast.models.networks import count_parameters, to_channels, training_forms
    from stylecast.models.restyle import restyle_clip, restyle_rotations
    from stylecast.motion import rotations as rot
    from stylecast.motion.words import DEFAULT_HOP

    restyler, kind = load_restyler(args.model, args.device)
    device = restyler.device
    G = restyler.generator()
    batches = [int(b) for b in args.batches.split(",")]
    many = random_words(max(batches + [64]))
    words = many[:64]
    feats = restyler.rep.encode(words)
    x64 = to_channels(torch.from_numpy(feats)).to(device)
    sync = torch.cuda.synchronize if device.type == "cuda" else (lambda: None)

    def synced(fn):  # a CUDA call returns before its kernels finish: time them to the end
        return lambda: (fn(), sync())

    rows = []
    baselines = {"  baseline: training layers (batch-dependent)": training_forms(G),  # oneDNN's kernels
                 "  baseline: the previous release's inference form": previous_inference_form(G)}
    with torch.no_grad():
        for n, goal in ((1, "<= 2 ms"), (8, ""), (64, "<= 40 ms")):
            x = x64[:n]
            rows.append((f"generator forward, {n} word{'s' * (n > 1)}", median_ms(synced(lambda: G(x)), args.repeats),
                         goal))
            for label, other in baselines.items():
                rows.append((label, median_ms(synced(lambda: other(x)), args.repeats), ""))
    rows.append(("restyle_words, 1 word (numpy in/out)",
                 median_ms(lambda: restyler.restyle_words(words[:1]), args.repeats), ""))
    rows.append(("restyle_words, 64 words (numpy in/out)",
                 median_ms(lambda: restyler.restyle_words(words), max(5, args.repeats // 3)), ""))
    # The daemon calls the model from a thread beside its busy output loop: what the GIL
    # costs a call (CPU: the calling thread's own; 1 ms is the daemon's switch interval).
    for switch in (0.005, 0.001):
        with busy_python_thread(switch):
            label = f"restyle_words, 8 words, busy Python thread beside it, GIL switch {switch * 1e3:g} ms"
            rows.append((label, median_ms(lambda: restyler.restyle_words(words[:8]), 10, 2, time.thread_time), ""))
            rows.append(("  baseline: the same operations eager (the previous release)",
                         median_ms(lambda: restyler.restyle_words_eager(words[:8]), 5 if switch > 0.002 else 10, 1, time.thread_time), ""))

    # The daemon's model thread's whole job on a tick's words (``InferenceWorker._call``):
    # the model's one traced call, hemisphere passes and check inside, against those passes
    # in numpy around ``restyle_words`` (the previous release), each of which handed the GIL
    # to the busy thread and waited to get it back. Wall time: the waiting is the cost.
    from stylecast.daemon.inference import InferenceWorker

    class NumpyAroundTheCall:  # the restyler without its one-call job
        restyle_words = restyler.restyle_words

    with busy_python_thread(0.001):
        for n in (8, 64):
            job = [(0, 59, w) for w in words[:n]]
            label = f"the model thread's job, {n} words, busy Python thread beside it, GIL switch 1 ms (wall)"
            rows.append((label, median_ms(lambda: InferenceWorker._call(restyler, job, words[:n]), 20, 2), ""))
            rows.append(("  baseline: numpy passes around restyle_words (the previous release)",
                         median_ms(lambda: InferenceWorker._call(NumpyAroundTheCall, job, words[:n]), 20, 2), ""))

    reader = getattr(restyler, "reader", None)
    if reader is not None:  # `--performer-style auto`: the same job with the style read from its words
        reading = restyler.with_performer_style("auto")
        with busy_python_thread(0.001):
            for n in (8, 64):
                job = [(0, 59, w) for w in words[:n]]
                rows.append((f"the model thread's job, {n} words, the performer's style read (auto; wall)",
                             median_ms(lambda: InferenceWorker._call(reading, job, words[:n]), 20, 2), ""))
                rows.append(("  baseline: the same job, the style named (wall)",
                             median_ms(lambda: InferenceWorker._call(restyler, job, words[:n]), 20, 2), ""))

    # restyle_words at growing batches: words/s with numpy in and out (what `restyle` and the
    # daemon hand it), and with the words already on the model's device (a tensor in and out).
    batch_rows = []
    for b in batches:
        reps = max(3, min(args.repeats, 2000 // b))
        on_device = torch.from_numpy(many[:b]).to(device)
        numpy_ms = median_ms(lambda: restyler.restyle_words(many[:b]), reps, 2)[0]
        tensor_ms = median_ms(synced(lambda: restyler.restyle_words(on_device)), reps, 2)[0]
        batch_rows.append((b, numpy_ms, b / numpy_ms * 1e3, tensor_ms, b / tensor_ms * 1e3))

    # Offline throughput: the stream part alone (humanoid rotations at 60 fps), and the
    # whole `restyle` path on a shared clip looped to about a minute (read/write excluded).
    T = 3600
    long = np.concatenate([words[i] for i in range(T // 60)])
    long = rot.canonical_hemisphere(long)
    thr = []
    for hop in (DEFAULT_HOP, 15, 60):  # DEFAULT_HOP: `restyle`'s and `serve`'s default
        thr.append((f"stream restyle at 60 fps, hop {hop} ({T} frames)",
                    *throughput(lambda: restyle_rotations(long, restyler.restyle_words, hop=hop), T)))
        thr.append((f"  stream code alone (identity model), hop {hop}",
                    *throughput(lambda: restyle_rotations(long, lambda w: w, hop=hop), T)))
    clip_path = DATA / "dataset-2_walk_normal_001.bvh.gz"
    if clip_path.exists():
        from stylecast.motion.bvh import read_bvh

        clip = read_bvh(clip_path)
        reps = max(1, int(60 * clip.fps) // clip.num_frames)
        idx = np.concatenate([np.arange(clip.num_frames) if i % 2 == 0 else np.arange(clip.num_frames)[::-1]
                              for i in range(reps)])
        looped = clip.replace(rotations=clip.rotations[idx], root_positions=clip.root_positions[idx],
                              translations=None if clip.translations is None else clip.translations[idx])
        for hop in (DEFAULT_HOP, 20, 60):
            wall, cpu = throughput(lambda: restyle_clip(looped, restyler, hop=hop), looped.num_frames)
            thr.append((f"`restyle` path, hop {hop}, Bandai {looped.fps:g} fps clip ({looped.num_frames} frames)",
                        wall, cpu))
            k = 60 / looped.fps
            thr.append(("  same, counted in 60 fps frames processed", wall * k, cpu * k))

    print(f"stylecast model benchmark ({kind} model {restyler.name}, generator "
          f"{count_parameters(G):,} parameters, representation {restyler.rep.name})")
    gpu = f", {torch.cuda.get_device_name(device)}" if device.type == "cuda" else ""
    print("machine: " + describe(f"torch {torch.__version__}, {args.threads} torch thread(s), model on {device}{gpu}"))
    print()
    w = max(len(r[0]) for r in rows + thr) + 2
    print(f"{'inference (median of ' + str(args.repeats) + ')':<{w}}{'wall ms':>10}{'CPU ms':>10}  goal")
    for name, (wall, cpu), goal in rows:
        print(f"{name:<{w}}{wall:>10.2f}{cpu:>10.2f}  {goal}")
    print()
    print(f"{'restyle_words on ' + str(device) + ' (median wall)':<{w}}{'ms':>10}{'words/s':>10}"
          f"{'ms':>10}{'words/s':>10}  (numpy in/out | tensor in/out on the device)")
    for b, numpy_ms, numpy_rate, tensor_ms, tensor_rate in batch_rows:
        print(f"{f'batch {b}':<{w}}{numpy_ms:>10.2f}{numpy_rate:>10,.0f}{tensor_ms:>10.2f}{tensor_rate:>10,.0f}")
    print()
    print(f"{'offline throughput':<{w}}{'frames/s':>10}{'per CPU s':>10}  "
          f"(goal >= 50,000 frames/s at the default hop, {DEFAULT_HOP})")
    for name, wall, cpu in thr:
        print(f"{name:<{w}}{wall:>10,.0f}{cpu:>10,.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
