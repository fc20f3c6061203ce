"""Clips shipped inside the package, so ``stylecast demo`` runs on a machine that has
nothing but the install (no ``../shared``).

They are two short recordings from the Bandai Namco Research Motion Dataset, dataset-2
(Kobayashi, Liao, Inoue, Yojima, Takahashi, "Motion Capture Dataset for Practical Use of
AI-based Motion Editing and Stylization", arXiv:2306.08861, 2023), licensed CC BY-NC 4.0:
non-commercial use only, attribution required. ``clips/ATTRIBUTION.md`` travels with
them. They are the dataset's own frames, rewritten by ``motion.bvh.write_bvh`` with 4
decimals (a tenth of a micrometre / ten-thousandth of a degree) and gzip, which halves the
download without changing the motion anyone can see.

Regenerate them from the shared data with ``python -m stylecast.daemon.clips ../shared/data``.
"""

from __future__ import annotations

import sys
from pathlib import Path

CLIPS_DIR = Path(__file__).resolve().parent / "clips"
# shipped name -> the dataset-2 file it was written from
BUNDLED = {
    "walk_normal.bvh.gz": "bandai/dataset-2/data/dataset-2_walk_normal_001.bvh.gz",
    "wave-right-hand_normal.bvh.gz": "bandai/dataset-2/data/dataset-2_wave-right-hand_normal_001.bvh.gz",
}
DEFAULT_BUNDLED = "walk_normal.bvh.gz"
PRECISION = 4


def bundled_clip(name: str = DEFAULT_BUNDLED) -> Path | None:
    """The shipped clip's path, or None when this install lacks it (a broken package)."""
    path = CLIPS_DIR / name
    return path if path.is_file() else None


def write_bundled_clips(data_root: Path, out_dir: Path = CLIPS_DIR) -> list[Path]:
    from stylecast.motion.bvh import read_bvh, write_bvh

    written = []
    for name, relative in BUNDLED.items():
        target = Path(out_dir) / name
        write_bvh(read_bvh(Path(data_root) / relative), target, precision=PRECISION)
        written.append(target)
    return written


if __name__ == "__main__":
    root = Path(sys.argv[1] if len(sys.argv) > 1 else "../shared/data")
    for path in write_bundled_clips(root):
        print(f"{path} ({path.stat().st_size} bytes)")
