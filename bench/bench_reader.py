"""How well the multi-style model's style reader (``--performer-style auto``) reads, and what
its reading does to a restyle. Not a speed benchmark: the reading's cost is in
``bench_models.py --model multistyle``.

    python bench/bench_reader.py [--model multistyle] [--takes 6]

Prints: held-out dataset-2 words (cut as the daemon cuts them) by true and read style; the
first pose of each held-out take held still for a word; dataset-1's words of the styles it
shares with dataset-2 (another recording: a stricter reading); and held-out takes served
towards their own style and towards another, read against named.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np
import torch

from stylecast.models import data as D
from stylecast.models.restyle import restyle_rotations
from stylecast.models.restyler import Restyler
from stylecast.models.styles import NEUTRAL, READ, STYLES
from stylecast.motion import rotations as rot
from stylecast.motion.words import DEFAULT_HOP, WORD_LENGTH

# Dataset-1's names for the styles dataset-2 also has (the rest are its own).
DATASET_1_STYLES = {"normal": "normal", "active": "active", "feminine": "feminine", "masculinity": "masculine",
                    "old": "elderly", "tired": "exhausted", "childish": "youthful"}
DATASET_1_NAME = re.compile(r"dataset-1_(?P<action>.+)_(?P<style>[^_]+)_(?P<take>\d+)\.bvh$")


def read_words(reader, rotations: np.ndarray) -> np.ndarray:
    """The reader's choice for each word of a take cut every DEFAULT_HOP frames."""
    words = D.cut_words(np.asarray(rotations, np.float64), DEFAULT_HOP)
    if not len(words):
        return np.zeros(0, int)
    return reader.read(torch.from_numpy(rot.canonical_hemisphere(words, axis=1))).argmax(axis=1)


def print_table(title: str, rows: dict[str, np.ndarray]) -> None:
    print(title)
    print(f"{'':<11}" + "".join(f"{s[:9]:>10}" for s in STYLES) + "     right")
    right = total = 0
    for style, counts in rows.items():
        k = STYLES.index(style)
        right, total = right + counts[k], total + counts.sum()
        print(f"{style:<11}" + "".join(f"{c:>10}" for c in counts) + f"   {100 * counts[k] / counts.sum():6.1f} %")
    print(f"overall {100 * right / total:.1f} % of {total} words\n")


def served_change(restyler, rotations: np.ndarray, like=None) -> np.ndarray:
    """Degrees each bone moves from ``like`` (default the input) when ``restyler`` serves the
    take (``restyle --live``), after the stream's first second (its first pose held)."""
    rotations = np.asarray(rotations, np.float64)
    out = restyle_rotations(rotations, restyler.restyle_words, DEFAULT_HOP, live=True).rotations
    return rot.angle_between(out, rotations if like is None else like)[WORD_LENGTH:].ravel()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="multistyle")
    ap.add_argument("--takes", type=int, default=6, help="held-out takes of each style served (default 6)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    model = Restyler.load(args.model)
    if getattr(model, "reader", None) is None:
        print(f"bench_reader: model {args.model} has no style reader; add one with `stylecast train-reader`",
              file=sys.stderr)
        return 2
    files = D.list_files()
    held_out = {s: D.load_motions(D.files_for_style(files, s, "val")) for s in STYLES}
    print(f"style reader of {model.name}: {model.metadata['reader'].get('training_words')} training words, "
          f"seed {model.metadata['reader'].get('seed')}\n")

    rows = {s: np.bincount(np.concatenate([read_words(model.reader, m.rotations) for m in takes]), minlength=7)
            for s, takes in held_out.items()}
    print_table(f"held-out dataset-2 words (hop {DEFAULT_HOP}), rows: the take's style", rows)

    still = {s: np.bincount(model.reader.read(torch.from_numpy(np.stack(
        [np.repeat(m.rotations[:1].astype(np.float64), WORD_LENGTH, 0) for m in takes]))).argmax(axis=1), minlength=7)
        for s, takes in held_out.items()}
    print_table("the first pose of each held-out take held still for a word (counted as words)", still)

    other = Path(D.default_data_dir()).parent.parent / "dataset-1" / "data"
    if other.is_dir():
        for title, actions in (("all actions", None), ("walks and runs", ("walk", "run"))):
            rows = {}
            for path in sorted(other.glob("*.bvh")):
                m = DATASET_1_NAME.match(path.name)
                if not m or m["style"] not in DATASET_1_STYLES or (actions and m["action"] not in actions):
                    continue
                style = DATASET_1_STYLES[m["style"]]
                rotations, _ = D.decode_file(path)
                counts = np.bincount(read_words(model.reader, rotations), minlength=7)
                rows[style] = rows.get(style, 0) + counts
            print_table(f"dataset-1 words (another recording), {title}, rows: its style by dataset-2's name",
                        {s: rows[s] for s in STYLES if s in rows})

    print(f"served towards the take's own style, after the first second: mean (p99) degrees a bone moves, "
          f"{args.takes} held-out takes of each style, hop {DEFAULT_HOP}")
    print(f"{'style':<11}{'taken as ' + NEUTRAL:>22}{'read (auto)':>22}{'named':>22}")
    for style in STYLES:
        target = model.for_target(style)
        cells = []
        for performer in (NEUTRAL, READ, style):
            moved = np.concatenate([served_change(target.with_performer_style(performer), m.rotations)
                                    for m in held_out[style][:args.takes]])
            cells.append(f"{moved.mean():.2f} ({np.percentile(moved, 99):.2f})")
        print(f"{style:<11}" + "".join(f"{c:>22}" for c in cells))
    print("\ntowards another style: read against named (degrees), and how far the restyle itself moves a bone")
    for source, target_style in (("elderly", "youthful"), ("normal", "elderly"), ("exhausted", "active")):
        target = model.for_target(target_style)
        read, moved = [], []
        for m in held_out[source][:args.takes]:
            rotations = m.rotations.astype(np.float64)
            like = restyle_rotations(rotations, target.with_performer_style(source).restyle_words, DEFAULT_HOP,
                                     live=True).rotations
            read.append(served_change(target.with_performer_style(READ), rotations, like))
            moved.append(served_change(target.with_performer_style(source), rotations))
        read, moved = np.concatenate(read), np.concatenate(moved)
        print(f"{source} -> {target_style}: read vs named mean {read.mean():.3f}, p99 {np.percentile(read, 99):.3f}, "
              f"max {read.max():.3f}; the restyle moves {moved.mean():.2f} on average")
    return 0


if __name__ == "__main__":
    sys.exit(main())
