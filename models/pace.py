"""How fast each style covers ground: the pace ``footlock.Pace`` gives a restyled stream.

The generator restyles poses; the root's horizontal path is not in its words. But styles
differ in speed over ground, and a window's travel is part of what reads as a style: real
held-out exhausted runs given the normal runs' speed read exhausted in 28 % of windows
(``stylecast eval``, "The ceiling of a restyle that keeps the input's travel"). So the
stream covers ground at the target style's pace: ``pace_points`` maps the input's speed to
the output's through the two styles' mean speeds in walks and in runs.

``PACES`` is measured on the training split only (the held-out files stay unseen), with
``measure_paces``; ``tests/test_pace.py`` checks the table against the data.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from stylecast.motion.clock import OUTPUT_FPS

WALKS = ("walk", "walk-turn-left", "walk-turn-right")
RUNS = ("run",)
# Mean horizontal root speed (cm/s) of each style's training clips: (walks, runs), the
# walking actions' means averaged. Standing actions are left out: their hips only sway.
PACES = {
    "active": (142.4, 338.8),
    "elderly": (71.3, 147.2),
    "exhausted": (103.7, 225.7),
    "feminine": (117.4, 266.2),
    "masculine": (114.4, 264.4),
    "normal": (109.8, 281.4),
    "youthful": (125.3, 280.6),
}


def pace_points(source: str, target: Mapping[str, float]) -> tuple[tuple[float, float], ...]:
    """``ContactSettings.pace`` for input of style ``source`` restyled towards the mix
    ``target`` (style -> weight, summing to 1): (input speed, output speed) in cm a frame
    at the stream's rate, one point for walks and one for runs; () where a style's pace is
    not known (the input's pace is kept)."""
    mix = {style: weight for style, weight in target.items() if weight > 0}
    if source not in PACES or not mix or any(style not in PACES for style in mix):
        return ()
    out = sum(weight * np.asarray(PACES[style]) for style, weight in mix.items()) / sum(mix.values())
    return tuple((float(a) / OUTPUT_FPS, float(b) / OUTPUT_FPS) for a, b in zip(PACES[source], out))


def measure_paces(files, cache_dir=None) -> dict[str, tuple[float, float]]:
    """``PACES`` from the dataset's training split: {style: (walks, runs)} in cm/s."""
    from .metrics import travel_speed

    return per_style_locomotion(files, lambda m: OUTPUT_FPS * travel_speed(m.root_positions), cache_dir)


def per_style_locomotion(files, read, cache_dir=None) -> dict[str, tuple[float, float]]:
    """{style: (walks, runs)}: ``read`` (a motion -> one figure) averaged over each style's
    training takes of each walking action and of runs, the walking actions' means averaged
    (the held-out files stay unseen); ``PACES`` and ``gait_amplitude``'s tables are read so."""
    from . import data as D

    out = {}
    for style in D.styles_present(files):
        motions = D.load_motions([f for f in D.files_for_style(files, style, "train") if f.action in WALKS + RUNS],
                                 cache_dir)
        mean = {a: float(np.mean([read(m) for m in motions if m.file.action == a])) for a in WALKS + RUNS}
        out[style] = (float(np.mean([mean[a] for a in WALKS])), float(np.mean([mean[a] for a in RUNS])))
    return out
