"""Choosing the torch device (``--device auto|cpu|cuda[:N]``) and making training
deterministic on it.

One place parses the flag for ``serve``, ``restyle`` and ``train``, so every command
refuses a bad device with the same sentence instead of a torch traceback.
"""

from __future__ import annotations

import os
import re
import warnings

from stylecast.motion.errors import UserError

DEVICE_CHOICES = "auto, cpu, cuda or cuda:N"
_DEVICE = re.compile(r"^(auto|cpu|cuda(:\d+)?)$")
# cuBLAS picks reduction orders at run time unless it is given a fixed workspace; without
# this setting torch refuses (or warns about) every matmul once determinism is asked for.
_CUBLAS_WORKSPACE = ":4096:8"
# torch's wording when an op has no deterministic implementation on the device.
_NONDETERMINISTIC = re.compile(r"^(\S+) does not have a deterministic implementation")


def check_device_name(name: str) -> str:
    """The --device value, normalised, or one sentence; needs no torch (config checks)."""
    text = str(name or "auto").strip().lower()
    if not _DEVICE.match(text):
        raise UserError(f"--device {name!r} is not a device; use {DEVICE_CHOICES}")
    return text


def pick_device(name="auto"):
    """A ``torch.device`` for a --device value; "auto" is the first CUDA device when
    there is one, else the CPU. Refuses unknown names and missing CUDA devices in one
    sentence."""
    import torch

    if isinstance(name, torch.device):
        name = str(name)
    text = check_device_name(name)
    if text == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if text.startswith("cuda"):
        if not torch.cuda.is_available():
            raise UserError(f"--device {text} was asked for but this machine has no CUDA device (or this torch "
                            f"is a CPU build); use --device cpu or auto")
        index = int(text.partition(":")[2] or 0)
        if index >= torch.cuda.device_count():
            raise UserError(f"--device {text} does not exist: this machine has {torch.cuda.device_count()} CUDA "
                            f"device(s), cuda:0 to cuda:{torch.cuda.device_count() - 1}")
    return torch.device(text)


class Determinism:
    """Deterministic algorithms for training on ``device``, never an exception.

    On the CPU every op stylecast uses has a deterministic implementation, so torch is
    told to raise (a new op without one is a bug to see at once). On CUDA some ops have
    none (``upsample_linear1d_backward`` in the generator up to issue 12): torch is told
    to warn instead, and ``watch()`` turns each such warning into ONE line for the user
    (per op, per run) rather than a traceback or a warning per step."""

    def __init__(self, device, log=print):
        import torch

        self.device = device
        self.log = log
        self.strict = device.type == "cpu"
        self.reported: set[str] = set()
        if device.type == "cuda":
            os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", _CUBLAS_WORKSPACE)
        torch.use_deterministic_algorithms(True, warn_only=not self.strict)

    def watch(self):
        """Context manager around training steps: reports ops that cannot be deterministic."""
        return _Watch(self)

    def report(self, message: str) -> bool:
        match = _NONDETERMINISTIC.match(message)
        if not match:
            return False
        op = match.group(1)
        if op not in self.reported:
            self.reported.add(op)
            self.log(f"note: {op} has no deterministic implementation on {self.device}; runs with the same seed "
                     f"may differ slightly there (the CPU is exact)")
        return True


class _Watch:
    def __init__(self, determinism: Determinism):
        self.determinism = determinism
        self._catch = warnings.catch_warnings(record=True)

    def __enter__(self):
        self._records = self._catch.__enter__()
        warnings.simplefilter("always")
        return self

    def __exit__(self, *exc):
        self._catch.__exit__(*exc)
        for w in self._records:  # anything that is not about determinism goes out as it came
            if not self.determinism.report(str(w.message)):
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        return False
