"""Trained judge panels kept on disk, so that a second `stylecast eval` on the same data
does not spend its first half hour training the same judges again.

Training the panel is most of an evaluation's time (1,634 of 1,740 s for one target with
``--threads 1`` on the Intel Xeon VM, 2026-11-30), and it is deterministic: the same code,
windows, seeds, torch and thread count give the same weights bit for bit on the same
machine. So the panel is stored under a key that covers all of those (``panel_key``): the
source of the modules that build and train the judges, every training window and label,
the members' designs and seeds, torch's version and its CPU threads, and the processor's
architecture. Change any of them and the key changes, so a stale panel is never read. (Any
edit of those modules, a comment too, retrains; another processor of the same architecture
could round a retrained panel differently, so a cache stays on the machine that wrote it,
as the decoded clips beside it do, ``data.default_cache_dir()``.) Files are safetensors
(nothing is unpickled) and written atomically. ``stylecast eval --fresh-judges`` trains anew.
"""

from __future__ import annotations

import hashlib
import os
import platform
from pathlib import Path

import numpy as np

# The modules whose code decides the judges' weights from their windows (the windows
# themselves are keyed by their bytes, so the code that cuts them need not be).
_SOURCES = ("judges.py", "classifier.py", "recurrent.py")
_FORMAT = "judge-panel-1"  # bump when the file's layout changes
_RNG = "torch_rng_state_after_training"


def panel_key(config: dict, arrays: list[np.ndarray]) -> str:
    """A hex digest of everything that decides a fitted panel's weights: ``config`` (names,
    designs, seeds: JSON-like values) and the training ``arrays`` (windows and labels)."""
    import torch

    h = hashlib.sha256()
    here = Path(__file__).parent
    for name in _SOURCES:
        h.update((here / name).read_bytes())
    h.update(repr((_FORMAT, sorted(config.items()), torch.__version__, torch.get_num_threads(),
                   platform.machine())).encode())
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(repr((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    return h.hexdigest()[:32]


def panel_path(cache_dir: Path, key: str) -> Path:
    return Path(cache_dir) / "judges" / f"panel-{key}.safetensors"


def save_panels(path: Path, panels: dict[str, list]) -> None:
    """Write each named list of fitted ``WordClassifier``s' weights to ``path``."""
    import torch
    from safetensors.torch import save_file

    tensors = {f"{name}.{k}.{param}": t.detach().contiguous().clone()
               for name, judges in panels.items() for k, j in enumerate(judges)
               for param, t in j.net.state_dict().items()}
    # Training draws from torch's global generator; what runs after the judges finds it where
    # training left it, so a read panel restores that too and the evaluation is the same.
    tensors[_RNG] = torch.get_rng_state()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    save_file(tensors, str(tmp))
    os.replace(tmp, path)  # atomic: a concurrent evaluation never reads half a file


def load_panels(path: Path, panels: dict[str, list]) -> bool:
    """Fill each named list of freshly built ``WordClassifier``s with the weights stored in
    ``path``; False (nothing changed) when there is no such file or it does not fit them."""
    import torch
    from safetensors import SafetensorError
    from safetensors.torch import load_file

    if not path.exists():
        return False
    try:
        stored = load_file(str(path))
        states = [(j, {param: stored[f"{name}.{k}.{param}"] for param in j.net.state_dict()})
                  for name, judges in panels.items() for k, j in enumerate(judges)]
        rng = stored[_RNG]
    except (SafetensorError, KeyError, OSError):
        return False  # a broken or foreign file: the caller trains and overwrites it
    for j, state in states:
        j.net.load_state_dict(state)
        j.net.eval()
    torch.set_rng_state(rng)
    return True
