"""Checkpoints: safetensors weights plus JSON metadata; nothing is ever unpickled.

``NAME.safetensors`` holds the tensors and, in its header, the metadata as one JSON
string (key ``stylecast``), so the file is self-contained; ``NAME.json`` beside it is a
readable copy of the same metadata (styles, bones, representation, normalisation, fps,
word length, training data and licence, git revision, network hyperparameters, metrics).
A SHA-256 of the tensor bytes is part of the metadata, so a flipped byte is caught too.

``load_checkpoint`` validates everything and raises ``UserError`` with one sentence for a
missing, truncated, corrupt or mismatched file.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
from pathlib import Path

import numpy as np

from stylecast.motion.errors import UserError

FORMAT = "stylecast-cyclegan"
FORMAT_VERSION = 1
CHECKPOINT_DIR = Path(__file__).resolve().parent / "checkpoints"
DEFAULT_MODEL = "normal2exhausted"
REQUIRED_KEYS = ("format", "format_version", "styles", "bones", "representation", "fps", "word_length",
                 "network", "weights_sha256", "licence")


def git_revision() -> str:
    repo = Path(__file__).resolve().parents[1]
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=repo, capture_output=True, text=True,
                             timeout=5)
        if out.returncode == 0 and out.stdout.strip():
            dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=repo,
                                   capture_output=True, text=True, timeout=5).stdout.strip()
            return out.stdout.strip() + ("-dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        pass
    return "unknown (no commit yet)"


def tensors_digest(tensors: dict[str, np.ndarray]) -> str:
    h = hashlib.sha256()
    for k in sorted(tensors):
        a = np.ascontiguousarray(tensors[k])
        h.update(k.encode())
        h.update(str(a.dtype).encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def resolve(path_or_name: str | os.PathLike | None) -> Path:
    """A path, or a bare name resolved to models/checkpoints/NAME.safetensors."""
    if path_or_name is None or str(path_or_name) == "":
        path_or_name = DEFAULT_MODEL
    s = str(path_or_name)
    p = Path(s)
    if p.suffix == ".json":
        p = p.with_suffix(".safetensors")
    if os.sep not in s and "/" not in s and p.suffix != ".safetensors":
        return CHECKPOINT_DIR / f"{s}.safetensors"
    return p


def available_models() -> list[str]:
    return sorted(p.stem for p in CHECKPOINT_DIR.glob("*.safetensors")) if CHECKPOINT_DIR.is_dir() else []


def save_checkpoint(path: str | os.PathLike, tensors: dict, metadata: dict, sidecar: bool = True) -> Path:
    """Write ``path`` (.safetensors) atomically, and ``path.json`` beside it."""
    from safetensors.numpy import save_file

    path = Path(path)
    arrays = {k: (v.detach().cpu().numpy() if hasattr(v, "detach") else np.asarray(v)) for k, v in tensors.items()}
    arrays = {k: np.ascontiguousarray(v) for k, v in arrays.items()}
    meta = dict(metadata)
    meta.setdefault("format", FORMAT)
    meta.setdefault("format_version", FORMAT_VERSION)
    meta["weights_sha256"] = tensors_digest(arrays)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    save_file(arrays, str(tmp), metadata={"stylecast": json.dumps(meta, sort_keys=True)})
    os.chmod(tmp, 0o644)  # safetensors creates owner-only files; checkpoints are shared
    os.replace(tmp, path)
    if sidecar:
        side = path.with_suffix(".json")
        tmp = side.with_name(f".{side.name}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n", encoding="utf-8")
        os.replace(tmp, side)
    return path


def read_checkpoint(path: str | os.PathLike) -> tuple[dict[str, np.ndarray], dict]:
    """Tensors and metadata of a checkpoint file, checked for integrity (not semantics)."""
    path = Path(path)
    if not path.is_file():
        names = ", ".join(available_models()) or "none"
        raise UserError(f"checkpoint {path} does not exist; pass --model with a .safetensors file or one of "
                        f"the shipped names ({names})")
    try:
        from safetensors import safe_open

        with safe_open(str(path), framework="numpy") as f:
            header = f.metadata() or {}
            tensors = {k: f.get_tensor(k) for k in f.keys()}
    except Exception as exc:  # safetensors raises its own error types for bad headers and short files
        raise UserError(f"checkpoint {path} is corrupt or truncated ({short_reason(exc)}); re-export it with "
                        f"`stylecast train` or restore the shipped file") from None
    try:
        meta = json.loads(header["stylecast"])
        if not isinstance(meta, dict):
            raise ValueError("metadata is not a table")
    except (KeyError, ValueError) as exc:
        raise UserError(f"checkpoint {path} has no stylecast metadata ({short_reason(exc)}); it was not written by "
                        f"stylecast, so export it again with `stylecast train`") from None
    missing = [k for k in REQUIRED_KEYS if k not in meta]
    if missing:
        raise UserError(f"checkpoint {path} lacks the metadata {', '.join(missing)}; export it again with "
                        f"`stylecast train`")
    if meta["format"] != FORMAT or meta["format_version"] != FORMAT_VERSION:
        raise UserError(f"checkpoint {path} has format {meta['format']} v{meta['format_version']}, this stylecast "
                        f"reads {FORMAT} v{FORMAT_VERSION}; use a matching stylecast or re-export the model")
    if tensors_digest(tensors) != meta["weights_sha256"]:
        raise UserError(f"checkpoint {path} is corrupt (its weights do not match their recorded SHA-256); "
                        f"restore the file or re-export it with `stylecast train`")
    return tensors, meta


def validate_metadata(path, meta: dict, bones: tuple[str, ...], word_length: int, fps: float) -> None:
    """Refuse metadata this stylecast cannot use, in one sentence. Values are type-checked
    before use: a hostile file must not turn into a TypeError or ValueError traceback."""
    if not (isinstance(meta["bones"], list) and all(isinstance(b, str) for b in meta["bones"])
            and isinstance(meta["word_length"], int) and isinstance(meta["fps"], (int, float))):
        raise UserError(f"checkpoint {path} has malformed metadata (bones must be a list of names, word_length "
                        f"an integer, fps a number); export it again with `stylecast train`")
    if tuple(meta["bones"]) != tuple(bones):
        raise UserError(f"checkpoint {path} was trained on the bones {meta['bones'][:3]}... which are not "
                        f"stylecast's {len(bones)} humanoid bones; retrain it for this stylecast")
    if int(meta["word_length"]) != word_length or float(meta["fps"]) != fps:
        raise UserError(f"checkpoint {path} expects {meta['word_length']}-frame words at {meta['fps']} fps, "
                        f"stylecast uses {word_length} at {fps:g}; retrain it for this stylecast")
    # The styles are each model kind's to check (``restyler.MODEL_KINDS``).


def check_shapes(path, module, tensors: dict[str, np.ndarray], prefixes: tuple[str, ...]) -> dict:
    """The state dict for the parts of ``module`` under ``prefixes``, after checking that the
    file has exactly those tensors with exactly those shapes."""
    import torch

    expected = {k: v for k, v in module.state_dict().items() if k.startswith(prefixes)}
    missing = sorted(set(expected) - set(tensors))
    if missing:
        raise UserError(f"checkpoint {path} does not match its network: tensor {missing[0]} is missing "
                        f"({len(missing)} in all); export it again with `stylecast train`")
    for k, v in expected.items():
        if tuple(tensors[k].shape) != tuple(v.shape):
            raise UserError(f"checkpoint {path} does not match its network: {k} has shape "
                            f"{tuple(tensors[k].shape)}, expected {tuple(v.shape)}; export it again with "
                            f"`stylecast train`")
    return {k: torch.from_numpy(np.array(tensors[k], dtype=np.float32)) for k in expected}


def update_metadata(path: str | os.PathLike, **updates) -> dict:
    """Rewrite a checkpoint with extra metadata (e.g. evaluation metrics)."""
    tensors, meta = read_checkpoint(path)
    meta.update(updates)
    save_checkpoint(path, tensors, meta)
    return meta


def short_reason(exc: BaseException) -> str:
    s = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return s[:120]
