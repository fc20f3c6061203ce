"""Training data: 60-frame motion words at 60 fps from the Bandai dataset-2, per style.

Files are ``dataset-2_{action}_{style}_{id}.bvh.gz``. Each file is read, retargeted to
the canonical humanoid (``Retarget.for_clip``), resampled from 30 to 60 fps and cached
as a small ``.npz`` (humanoid local rotations, float32) under the cache directory
(``$STYLECAST_CACHE``, else ``$XDG_CACHE_HOME/stylecast``, else ``~/.cache/stylecast``),
so a second run starts in seconds. Never commit the cache.

Train/validation split BY FILE, never by word: a file is held out when the first 32 bits
of the SHA-1 of its name, as a fraction of 2**32, fall below 0.15. Deterministic,
independent of which other files exist, and the same for every pair of styles.

Words are cut with a hop (20 frames for training, so neighbouring words overlap by
two thirds), their heading is removed (``representation.remove_heading``) and they are
encoded by the chosen representation.
"""

from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from stylecast.motion.clock import OUTPUT_FPS as FPS  # the one definition of the frame rate
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import RETARGET_VERSION
from stylecast.motion.mirror import mirror_rotations
from stylecast.motion.words import WORD_LENGTH  # the one definition of a word's length

from . import representation as R

VAL_FRACTION = 0.15
CACHE_VERSION = f"h{RETARGET_VERSION}"  # follows the retargeting; bump the suffix if resampling changes
FILE_RE = re.compile(r"^dataset-2_(?P<action>.+)_(?P<style>[a-z]+)_(?P<take>\d+)\.bvh(?:\.gz)?$")
DATA_LICENCE = "CC BY-NC 4.0, non-commercial"
DATA_NAME = "Bandai Namco Research Motion Dataset, dataset-2"


def default_data_dir() -> Path:
    env = os.environ.get("STYLECAST_DATA")
    if env:
        return Path(env)
    # The repository sits next to ../shared (see the project layout).
    return Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bandai" / "dataset-2" / "data"


def default_cache_dir() -> Path:
    env = os.environ.get("STYLECAST_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or (Path.home() / ".cache")
    return Path(base) / "stylecast"


@dataclass(frozen=True)
class MotionFile:
    path: Path
    action: str
    style: str
    take: int
    mirrored: bool = False  # the take's left-right mirror image (``mirror_file``), for training only

    @property
    def name(self) -> str:
        return self.path.name

    @property
    def is_validation(self) -> bool:
        return is_validation_name(self.name)


def is_validation_name(name: str, fraction: float = VAL_FRACTION) -> bool:
    h = int(hashlib.sha1(name.encode("utf-8")).hexdigest()[:8], 16)
    return h / 2 ** 32 < fraction


def list_files(data_dir: Path | str | None = None) -> list[MotionFile]:
    data_dir = Path(data_dir) if data_dir else default_data_dir()
    if not data_dir.is_dir():
        raise UserError(f"dataset folder {data_dir} does not exist; pass --data with the Bandai dataset-2 "
                        f"'data' folder or set STYLECAST_DATA")
    files = []
    for p in sorted(data_dir.iterdir()):
        m = FILE_RE.match(p.name)
        if m:
            files.append(MotionFile(p, m["action"], m["style"], int(m["take"])))
    if not files:
        raise UserError(f"no dataset-2_{{action}}_{{style}}_{{id}}.bvh.gz files in {data_dir}; pass --data with "
                        f"the Bandai dataset-2 'data' folder")
    return files


def styles_present(files: list[MotionFile]) -> list[str]:
    return sorted({f.style for f in files})


def actions_present(files: list[MotionFile]) -> list[str]:
    return sorted({f.action for f in files})


def files_for_style(files: list[MotionFile], style: str, split: str = "train") -> list[MotionFile]:
    """Files of one style; split is "train", "val" or "all"."""
    present = styles_present(files)
    if style not in present:
        raise UserError(f"unknown style {style!r}; the data has the styles {', '.join(present)}")
    chosen = [f for f in files if f.style == style]
    if split == "train":
        chosen = [f for f in chosen if not f.is_validation]
    elif split == "val":
        chosen = [f for f in chosen if f.is_validation]
    return chosen


def bandai_skeleton(files: list[MotionFile]):
    """The humanoid skeleton of the Bandai actors (every file shares one rig)."""
    from stylecast.motion.bvh import read_bvh
    from stylecast.motion.humanoid import Retarget

    clip = read_bvh(files[0].path)
    return Retarget.for_clip(clip).to_humanoid(clip).skeleton


# --- decoding and caching -------------------------------------------------------------

@dataclass(frozen=True)
class HumanoidMotion:
    """One file's humanoid motion at 60 fps."""

    file: MotionFile
    rotations: np.ndarray  # (T, 22, 4) float32 local quaternions
    root_positions: np.ndarray  # (T, 3) float32, centimetres

    @property
    def num_frames(self) -> int:
        return int(self.rotations.shape[0])


def decode_file(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a BVH, retarget to the humanoid, resample to 60 fps: (rotations, root)."""
    from stylecast.motion.bvh import read_bvh
    from stylecast.motion.humanoid import Retarget
    from stylecast.motion.resample import resample

    clip = read_bvh(path)
    humanoid = Retarget.for_clip(clip).to_humanoid(clip)
    humanoid = resample(humanoid, FPS)
    return humanoid.rotations.astype(np.float32), humanoid.root_positions.astype(np.float32)


def load_motion(file: MotionFile, cache_dir: Path | None = None) -> HumanoidMotion:
    cache_dir = Path(cache_dir) if cache_dir else default_cache_dir()
    stat = file.path.stat()
    key = f"{file.path.name}.{CACHE_VERSION}.{stat.st_size}.{int(stat.st_mtime)}.npz"
    cached = cache_dir / key
    if cached.exists():
        try:
            with np.load(cached, allow_pickle=False) as z:
                return HumanoidMotion(file, z["rotations"], z["root_positions"])
        except (OSError, ValueError, KeyError):
            pass  # a broken cache entry is rebuilt below
    rotations, root = decode_file(file.path)
    cache_dir.mkdir(parents=True, exist_ok=True)
    tmp = cached.with_name(f".{cached.name}.{os.getpid()}.tmp.npz")
    np.savez(tmp, rotations=rotations, root_positions=root)
    os.replace(tmp, cached)  # atomic: concurrent runs never read half a file
    return HumanoidMotion(file, rotations, root)


def load_motions(files: list[MotionFile], cache_dir: Path | None = None, progress: bool = False,
                 max_words: int | None = None, hop: int = 20) -> list[HumanoidMotion]:
    """Load files in order; with ``max_words`` stop once that many words are available."""
    out, words = [], 0
    it = files
    if progress:
        from tqdm import tqdm

        it = tqdm(files, desc="loading clips", unit="file", leave=False)
    for f in it:
        m = load_motion(f, cache_dir)
        out.append(m)
        words += num_words(m.num_frames, hop)
        if max_words is not None and words >= max_words:
            break
    return out


# --- words ------------------------------------------------------------------------------

def num_words(num_frames: int, hop: int, length: int = WORD_LENGTH) -> int:
    return 0 if num_frames < length else (num_frames - length) // hop + 1


def cut_words(rotations: np.ndarray, hop: int, length: int = WORD_LENGTH) -> np.ndarray:
    """(T, J, 4) -> (N, length, J, 4) words starting every ``hop`` frames."""
    n = num_words(len(rotations), hop, length)
    if n == 0:
        return np.zeros((0, length, *rotations.shape[1:]), dtype=rotations.dtype)
    starts = np.arange(n) * hop
    idx = starts[:, None] + np.arange(length)[None, :]
    return rotations[idx]


@dataclass
class WordSet:
    """Heading-free quaternion words of one style, ``words`` (N, 60, J, 4) float32, with
    the index of the file each word came from. ``features(rep)`` encodes them."""

    style: str
    words: np.ndarray
    file_index: np.ndarray
    files: list[MotionFile]

    def __len__(self) -> int:
        return len(self.words)

    def features(self, representation: R.Representation, chunk: int = 2048) -> np.ndarray:
        out = np.empty((*self.words.shape[:3], representation.channels), np.float32)
        for i in range(0, len(self.words), chunk):
            out[i:i + chunk] = representation.encode(self.words[i:i + chunk])
        return out


def mirror_action(action: str) -> str:
    """The action a mirror image performs: walk-turn-left <-> walk-turn-right, the one-hand
    raises and waves likewise; every other action is its own mirror image."""
    swap = {"left": "right", "right": "left"}
    return "-".join(swap.get(part, part) for part in action.split("-"))


def mirror_file(file: MotionFile) -> MotionFile:
    return replace(file, action=mirror_action(file.action), mirrored=not file.mirrored)


def with_mirror(wordset: WordSet) -> WordSet:
    """The words and, after them, their left-right mirror images (``motion.mirror``), each
    image labelled with its mirrored take (so its action is the mirrored action and
    ``next_words`` still finds the next word of the same take).

    Why: a generator trained on both sides has no side to prefer. Trained on the takes as
    recorded, the default restyle took left-turning walks for straight walks in 26.7 % of
    windows and right-turning ones in 13.0 % (the input's own: 12.9 % and 5.6 %)."""
    return WordSet(wordset.style, np.concatenate([wordset.words, mirror_rotations(wordset.words)]),
                   np.concatenate([wordset.file_index, wordset.file_index + len(wordset.files)]),
                   wordset.files + [mirror_file(f) for f in wordset.files])


def next_words(wordset: "WordSet") -> np.ndarray:
    """For each word of a set cut in take order, the index of the next word of the same
    take (they overlap by length - hop frames), or -1 at the end of a take."""
    nxt = np.arange(1, len(wordset) + 1)
    same = np.append(wordset.file_index[1:] == wordset.file_index[:-1], False)
    return np.where(same, nxt, -1)


def headless(words: np.ndarray) -> np.ndarray:
    """Quaternion words (N, 60, J, 4) with their heading removed, float32."""
    if len(words) == 0:
        return np.asarray(words, np.float32)
    flat, _ = R.remove_heading(np.asarray(words, np.float64))
    return flat.astype(np.float32)


def build_wordset(motions: list[HumanoidMotion], style: str, hop: int = 20,
                  max_words: int | None = None) -> WordSet:
    words, index = [], []
    for i, m in enumerate(motions):
        w = cut_words(m.rotations, hop)
        words.append(w)
        index.append(np.full(len(w), i))
    words_arr = np.concatenate(words) if words else np.zeros((0, WORD_LENGTH, 22, 4), np.float32)
    index_arr = np.concatenate(index) if index else np.zeros(0, int)
    if max_words is not None:
        words_arr, index_arr = words_arr[:max_words], index_arr[:max_words]
    return WordSet(style, headless(words_arr), index_arr, [m.file for m in motions])


def load_wordset(style: str, split: str, data_dir=None, cache_dir=None, hop: int = 20,
                 max_words: int | None = None, progress: bool = False, mirror: bool = False) -> WordSet:
    """One style's words of a split; with ``mirror``, followed by their mirror images
    (``with_mirror``; ``max_words`` counts the recorded words)."""
    files = files_for_style(list_files(data_dir), style, split)
    if max_words is not None:
        # Spread a small subset over the takes deterministically instead of one action only.
        files = sorted(files, key=lambda f: hashlib.sha1(f.name.encode()).hexdigest())
    motions = load_motions(files, cache_dir, progress, max_words, hop)
    words = build_wordset(motions, style, hop, max_words)
    return with_mirror(words) if mirror else words
