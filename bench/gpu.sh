#!/usr/bin/env bash
# The GPU figures of issue 12, each beside its CPU baseline on the same machine:
#   bash bench/gpu.sh OUTDIR [SECONDS]
# needs stylecast installed, a CUDA device and Bandai dataset-2 clips where the tests look for
# them (../shared/data/bandai/dataset-2/data, or $STYLECAST_DATA): normal and exhausted for the
# pair, every style for the multistyle timing (a third of each style's files is enough: an
# epoch is a fixed number of words, so its time does not depend on the set). Each step has its own time
# limit and log in OUTDIR, so one that fails or overruns leaves the others' figures; the
# whole ends within SECONDS (default 560), the most important steps first.
set -u
out=${1:?usage: bash bench/gpu.sh OUTDIR [SECONDS]}
budget=${2:-560}
mkdir -p "$out"
repo=$(cd "$(dirname "$0")/.." && pwd)
cd "$repo"
export PYTHONUNBUFFERED=1
ulimit -n 65536 2>/dev/null  # a thousand performers' sockets

step() {  # step NAME SECONDS COMMAND...: run, log to OUTDIR/NAME.log, say how it ended
    local name=$1 limit=$2 left=$((budget - SECONDS))
    shift 2
    ((limit > left)) && limit=$left
    ((limit < 10)) && { echo "== $name: skipped, no time left"; return; }
    local t0=$SECONDS
    timeout "$limit" "$@" >"$out/$name.log" 2>&1
    echo "== $name: exit $? after $((SECONDS - t0)) s"
}

nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader >"$out/gpu.txt" 2>&1

train() {  # seconds per epoch of the shipped recipe's training on device $1
    step "train-$1" "$2" python3 -m stylecast train --style-a normal --style-b exhausted --loss cycle-diff \
        --lambda-action 0.25 --seed 3 --epochs 3 --device "$1" --out "/tmp/gpu-train-$1"
    cp "/tmp/gpu-train-$1/losses.csv" "$out/train-$1.csv" 2>/dev/null
}
train_all() {  # seconds per epoch of the multistyle model's training on device $1
    step "train-all-$1" "$2" python3 -m stylecast train --styles all --seed 1 --epochs 3 --device "$1" \
        --out "/tmp/gpu-train-all-$1" --no-progress
    cp "/tmp/gpu-train-all-$1/losses.csv" "$out/train-all-$1.csv" 2>/dev/null
}
capacity() {  # serve --device $1: performers in one process (on the 2026-11-27 H100 host one
    # process held 32 with CUDA, as many as any), then over one worker process per core (on
    # the first H100 host, 16 workers held 8 performers and not 16, see the README)
    step "capacity1-$1" "$(($2 / 2))" python3 bench/bench_daemon.py capacity 5 --device "$1" \
        --sizes 8,16,32,64,128,256 --no-baseline
    step "capacity-$1" "$(($2 / 2))" python3 bench/bench_daemon.py capacity-workers 5 --device "$1" \
        --sizes 8,16,32,64,128,256,512,1024 --no-baseline
}

# The tests that run only where CUDA is (skipped on CI's CPU machine).
step cuda-tests 90 python3 -m pytest -q -p no:cacheprovider tests/test_train_device.py \
    tests/test_representation_torch.py
# On the GPU: restyle_words at batch 1/64/4096 and offline throughput, training, capacity.
step models-cuda 90 python3 bench/bench_models.py --device cuda --repeats 10
train cuda 100
train_all cuda 60
capacity cuda 120
# The baselines on the same machine: its whole CPU for the model bench and the training,
# one torch thread per worker process (serve's setting) for capacity.
step models-cpu 80 python3 bench/bench_models.py --device cpu --threads "$(nproc)" --repeats 5
train cpu 80
train_all cpu 40
capacity cpu 80
