"""The epoch loop both trainers share (``train.py``, pairs; ``train_multistyle.py``, the
multistyle model) and the state ``--resume`` reads back.

A trainer has ``cfg`` (``epochs``, ``to_dict``), ``epoch``, ``run_epoch(bar)``,
``validate()``, ``save(out, metrics)``, ``load_state(out)``, the optimisers ``opt_g`` and
``opt_d``, ``model`` and ``average`` (a ``WeightAverage`` or None). Files in the output folder:
``losses.csv`` (one row an epoch), ``train_state.safetensors`` (optimiser moments, the weight
average, the settings), ``config.json`` and the shippable ``model*.safetensors``.
"""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import numpy as np

from stylecast.motion.errors import UserError

from . import checkpoint as ckpt
from .averaging import WeightAverage

AVERAGE_PREFIX = "average."  # the weight average's tensors in train_state.safetensors

OPTIMISERS = ("opt_g", "opt_d")  # the trainers' attribute names


def write_train_state(out: Path, trainer, meta: dict) -> None:
    """``out/train_state.safetensors``: what ``--resume`` needs beyond the weights in
    ``checkpoint.safetensors``: both optimisers' moments, the weight average and the
    settings (``trainer`` has ``opt_g``, ``opt_d``, ``average`` and ``cfg``)."""
    state, layout = {}, {}
    for name in OPTIMISERS:
        sd = getattr(trainer, name).state_dict()
        layout[name] = {"param_groups": sd["param_groups"]}
        for pid, s in sd["state"].items():
            for k, v in s.items():
                state[f"{name}.{pid}.{k}"] = v.reshape(1) if v.dim() == 0 else v
    meta = {**meta, "optimisers": layout, "config": trainer.cfg.to_dict()}
    if trainer.average is not None:
        state.update(trainer.average.tensors(AVERAGE_PREFIX))
        meta["average_updates"] = trainer.average.updates
    ckpt.save_checkpoint(out / "train_state.safetensors", state, meta)


def read_train_state(out: Path, trainer, config_type, prefixes: tuple[str, ...]) -> None:
    """Restore ``trainer`` from ``out`` (weights under ``prefixes``, optimisers, average,
    epoch), refusing in one sentence a run whose settings (bar the epochs) differ."""
    import torch

    tensors, _ = ckpt.read_checkpoint(out / "checkpoint.safetensors")
    trainer.model.load_state_dict(ckpt.check_shapes(out / "checkpoint.safetensors", trainer.model, tensors, prefixes))
    st, smeta = ckpt.read_checkpoint(out / "train_state.safetensors")
    saved = config_type.from_dict(smeta["config"]).to_dict()
    mine = trainer.cfg.to_dict()
    changed = sorted(k for k in mine if k not in ("epochs",) and saved.get(k) != mine[k])
    if changed:
        raise UserError(f"cannot resume from {out}: the run used different settings ({', '.join(changed)}); "
                        f"use the same options or a new --out folder")
    for name in OPTIMISERS:
        state: dict = {}
        prefix = f"{name}."
        for k, v in st.items():
            if k.startswith(prefix):
                pid, key = k[len(prefix):].split(".", 1)
                t = torch.from_numpy(np.array(v))
                state.setdefault(int(pid), {})[key] = t.reshape(()) if key == "step" else t
        getattr(trainer, name).load_state_dict({"state": state, "param_groups": smeta["optimisers"][name]["param_groups"]})
    trainer.epoch = int(smeta["epochs_completed"])
    if trainer.average is not None:
        trainer.average.load(st, smeta.get("average_updates", 0), AVERAGE_PREFIX)


def timed_epoch(trainer, bar=None) -> dict:
    """One training epoch and its validation, with its wall and CPU seconds (the machine
    is shared: CPU time is the fair cost)."""
    t0, c0 = time.perf_counter(), time.process_time()
    row = trainer.run_epoch(bar)
    row.update(trainer.validate())
    row["epoch"] = trainer.epoch
    row["seconds"] = time.perf_counter() - t0
    row["cpu_seconds"] = time.process_time() - c0
    return row


def write_models(out: Path, last: dict, average: WeightAverage | None, metadata, log=print) -> None:
    """``model.safetensors``: the shippable generator(s), the weight average when the run kept
    one (then the last weights go to ``model-raw.safetensors``, for the ablation).
    ``metadata(tensors)``: the metadata of a file holding those tensors."""
    files = [("model.safetensors", last, "the last training step's")]
    if average is not None:
        files = [("model-raw.safetensors", last, "the last training step's"),
                 ("model.safetensors", average.tensors(), average.describe())]
        log(f"model.safetensors holds the weight average ({average.describe()}); the last weights are in "
            f"{out / 'model-raw.safetensors'}")
    for name, tensors, weights in files:
        ckpt.save_checkpoint(out / name, tensors, {**metadata(tensors), "weights": weights})


def write_csv(path: Path, rows: list[dict], fields: tuple[str, ...]) -> None:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def _read_csv(path: Path) -> list[dict]:
    if not path.exists():
        return []
    with open(path, newline="") as f:
        return [{k: (float(v) if v not in ("", None) and k != "epoch" else v) for k, v in r.items()}
                for r in csv.DictReader(f)]


def check_resumable(out: Path) -> None:
    if not (out / "checkpoint.safetensors").exists() or not (out / "train_state.safetensors").exists():
        raise UserError(f"nothing to resume in {out}: no checkpoint.safetensors and train_state.safetensors "
                        f"there; drop --resume to start a new run")


def run_epochs(trainer, out: Path, steps_per_epoch: int, fields, resume: bool, progress: bool, log) -> dict:
    """The epoch loop both trainers share (``trainer``: ``cfg``, ``epoch``, ``run_epoch``,
    ``validate``, ``save(out, metrics)``, ``load_state(out)``): resume where a run stopped,
    one CSV row and one checkpoint per epoch; returns the final metrics."""
    cfg = trainer.cfg
    rows: list[dict] = []
    if resume:
        check_resumable(out)
        trainer.load_state(out)
        rows = [r for r in _read_csv(out / "losses.csv") if int(r["epoch"]) <= trainer.epoch]
        log(f"resuming from epoch {trainer.epoch}")
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=steps_per_epoch * (cfg.epochs - trainer.epoch), unit="step", dynamic_ncols=True)
    spent = sum(float(r.get("seconds") or 0) for r in rows)
    cpu = sum(float(r.get("cpu_seconds") or 0) for r in rows)
    while trainer.epoch < cfg.epochs:
        if bar is not None:
            bar.set_description(f"epoch {trainer.epoch + 1}/{cfg.epochs}")
        row = timed_epoch(trainer, bar)
        spent += row["seconds"]
        cpu += row["cpu_seconds"]
        rows.append(row)
        write_csv(out / "losses.csv", rows, fields)
        trainer.save(out, {"train_seconds": spent, "train_cpu_seconds": cpu,
                           **{k: v for k, v in row.items() if k.startswith("val_")}})
        if bar is None:
            log(f"epoch {trainer.epoch}/{cfg.epochs} " + " ".join(f"{k}={row[k]:.4g}" for k in fields[1:] if k in row))
    if bar is not None:
        bar.close()
    return {"train_seconds": spent, "train_cpu_seconds": cpu, "epochs": trainer.epoch,
            **{k: v for k, v in (rows[-1] if rows else {}).items() if k.startswith("val_")}}


def finish(out: Path, cfg, final: dict, log) -> None:
    (out / "config.json").write_text(json.dumps(cfg.to_dict(), indent=2) + "\n")
    log(f"done: {final['epochs']} epochs in {final['train_seconds'] / 60:.1f} min "
        f"({final['train_cpu_seconds'] / 60:.1f} CPU min); model at {out / 'model.safetensors'}")
