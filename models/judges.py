"""The evaluation's judges: a 7-style and a 10-action classifier over world joint
positions, trained on the training split of every dataset-2 style.

What a judge sees (``judge_windows``): 60-frame windows of forward-kinematics joint
positions in metres, relative to the hips at the window's centre frame and turned so the
hips face +Z there. The root's path inside the window is kept (a judge may notice that a
restyled walk still walks at the input's speed: the root is passed through, and that is
an honest limit of the restyle), the performer's place and facing in the room are not.
The classifier (``classifier.WordClassifier``) sees these positions and their velocities.

Style is judged over one motion word (60 frames, 1 s); actions over two seconds
(``ACTION_WINDOW``), with the one-word action judges kept as a stricter reading.
"""

from __future__ import annotations

import numpy as np

from . import data as D
from . import judge_cache as JC
from . import representation as R
from .classifier import WordClassifier
from .metrics import world_positions

WINDOW = 60
JUDGE_HOP = 30  # windows overlap by half: more samples for the Frechet statistics

# Frames an action judge sees (2 s at 60 fps). A turning walk turns for 1.5-2.5 s in the
# middle of its take, with about a second of straight walking before and after (heading
# change per 1 s window of held-out takes: 30-90 degrees in the turn, under 10 at either
# end). One second of those straight parts is a walk whatever the take is called: one-word
# judges read the unchanged normal input's actions right in only 90.9-93.5 % of windows (its
# walks and turning walks 76-89 %, every other action 95-100 %), under the 93 % goal itself,
# and what the default lost to them was straight windows of turning takes. Over two seconds
# the same designs read the input right in 97.6 % (the issue's own judge: 98 %). They are
# not simply more lenient (they read the default's left raises as waves in 29 % of windows,
# one-word judges in 14 %), but the one-word action judges, under which no restyle can
# reach what the input cannot, stay in the report as a stricter reading.
ACTION_WINDOW = 120


def judge_windows(rotations: np.ndarray, roots: np.ndarray, skeleton, hop: int = JUDGE_HOP,
                  window: int = WINDOW) -> np.ndarray:
    """(T, J, 4) rotations and (T, 3) roots -> (N, window, J, 3) judge inputs (none from a
    take shorter than the window)."""
    positions = world_positions(rotations, roots, skeleton) / 100.0
    starts = np.arange(0, len(positions) - window + 1, hop)
    if len(starts) == 0:
        return np.zeros((0, window, positions.shape[1], 3), np.float32)
    idx = starts[:, None] + np.arange(window)
    words = positions[idx]  # (N, window, J, 3)
    yaw = R.word_heading(np.asarray(rotations, np.float64)[idx])  # hips' facing at each centre frame
    centre = words[:, window // 2 : window // 2 + 1, :1]  # (N, 1, 1, 3) hips at the centre frame
    c, s = np.cos(-yaw), np.sin(-yaw)
    rel = words - centre
    x = c[:, None, None] * rel[..., 0] + s[:, None, None] * rel[..., 2]
    z = -s[:, None, None] * rel[..., 0] + c[:, None, None] * rel[..., 2]
    return np.stack([x, rel[..., 1], z], axis=-1).astype(np.float32)


# Judges of each kind in the panel. Two classifiers of the same design, trained on the same
# windows from different random seeds, are both right on 99-100 % of real held-out windows
# and still disagree badly on restyled ones: the shipped default read exhausted in 90.9 %
# of windows to the seed-0 judge and 73.7 % to the seed-1 judge, and the first shipped
# model 67.7 % against 35.7 %. Retrained on another machine (float rounding), the same
# seeds read the default 87.3 % and 65.2 %, and seed 2 96.6 %. A model picked on one
# judge's figures fits that judge's quirks; the panel's worst judge is the figure a goal
# is read on.
PANEL = 3

# Recurrent judges in each panel beside the convolutional ones: a bidirectional GRU over the
# frames (``classifier._recurrent_net``), as right on real held-out windows (style 98.7-100 %,
# action 88-96 %) but of another design, so a model cannot pass on the quirks that three
# seeds of one design share. A run trained on mirrored takes (MODEL_CARD.md) read exhausted
# in 67.7-90.9 % of windows to the three conv judges and 94.1 % to the GRU judge; the default
# 92.1-96.0 % and 92.1 %. The goals are read on the worst judge of either design.
RECURRENT_PANEL = 1

# Dynamics judges: 7-style classifiers of the same kind that see only the joints'
# velocities (``WordClassifier(velocity_only=True)``, seed 004's view of style as motion
# dynamics). They are right on 96-100 % of real held-out windows of every style, yet read a
# restyle that only moves the posture as what it is: the posture-only baseline, 45 %
# exhausted to the full judges, is 1-4 % exhausted to them, and the previous default (v2)
# 26-38 % (87 % to the full judge of the same seed). Their figure is a stricter goal beside the
# issue's.
DYNAMICS_PANEL = 2


class Judges:
    """Panels of style and action classifiers trained on real windows of the training split:
    ``panel`` conv judges (seeds ``seed``, ``seed + 1``, ...) then ``recurrent`` GRU judges
    (seeds ``seed``, ...), the ``members``; and ``dynamics`` style classifiers that see only
    velocities (seeds ``seed``, ...). The style judges see one-word windows
    (``judge_windows``), the action judges ``ACTION_WINDOW`` frames (``action_windows``)
    and the short action judges, the same members again, one-word windows. The first of
    each is the judge reports had before the panel (same seed, same figures on the same
    machine); its pooled features are the style space plotted."""

    def __init__(self, styles: list[str], actions: list[str], seed: int = 0, panel: int = PANEL,
                 dynamics: int = DYNAMICS_PANEL, recurrent: int = RECURRENT_PANEL):
        if panel < 1 or dynamics < 0 or recurrent < 0:
            raise ValueError(f"a judge panel needs at least one judge of each kind and dynamics and recurrent "
                             f"counts of zero or more, got {panel}, {dynamics} and {recurrent}")
        self.styles, self.actions = list(styles), list(actions)
        self.seeds = [seed + k for k in range(panel)]
        # (design, seed) of each style and action judge, in panel order: the conv judges first.
        self.members = [("conv", s) for s in self.seeds] + [("gru", seed + k) for k in range(recurrent)]
        self.dynamics_seeds = [seed + k for k in range(dynamics)]
        self.style_panel: list[WordClassifier] = []
        self.action_panel: list[WordClassifier] = []
        self.short_action_panel: list[WordClassifier] = []
        self.dynamics_panel: list[WordClassifier] = []

    @property
    def style(self) -> WordClassifier:
        return self.style_panel[0]

    @property
    def action(self) -> WordClassifier:
        return self.action_panel[0]

    def fit(self, motions: list, skeleton, log=print, cache_dir=None, fresh: bool = False) -> "Judges":
        """Train every panel on ``motions``' windows; with ``cache_dir``, read them from a
        panel trained earlier on the same windows by the same code instead (unless
        ``fresh``), or store the new one there (``judge_cache``)."""
        def windows_of(make):
            w = [make(m.rotations, m.root_positions, skeleton) for m in motions]
            labels = lambda of: np.concatenate([np.full(len(x), of(m)) for x, m in zip(w, motions)])
            return (np.concatenate(w), labels(lambda m: self.styles.index(m.file.style)),
                    labels(lambda m: self.actions.index(m.file.action)))

        x, ys, ya = windows_of(judge_windows)
        xa, _, ya_long = windows_of(self.action_windows)
        features = x.shape[2] * x.shape[3]

        # name: (classes, windows, labels, [(design, seed, velocity_only)]), in training order
        specs = {"style": (self.styles, x, ys, [(d, s, False) for d, s in self.members]),
                 "action": (self.actions, xa, ya_long, [(d, s, False) for d, s in self.members]),
                 "short_action": (self.actions, x, ya, [(d, s, False) for d, s in self.members]),
                 "dynamics": (self.styles, x, ys, [("conv", s, True) for s in self.dynamics_seeds])}

        def build(train: bool) -> dict[str, list[WordClassifier]]:
            # Each judge is fitted as soon as it is built: building seeds torch's generator,
            # and its fit's dropout draws from there on (the figures before the cache).
            fitted = (lambda j, w, y: j.fit(w, y)) if train else (lambda j, w, y: j)
            return {name: [fitted(WordClassifier(classes, features, s, velocity_only=v, design=d), w, y)
                           for d, s, v in members]
                    for name, (classes, w, y, members) in specs.items()}

        path, panels = None, None
        if cache_dir is not None:
            config = {"styles": self.styles, "actions": self.actions, "members": self.members,
                      "dynamics": self.dynamics_seeds}
            path = JC.panel_path(cache_dir, JC.panel_key(config, [x, ys, xa, ya_long, ya]))
            if not fresh:
                panels = build(train=False)
                if not JC.load_panels(path, panels):
                    panels = None
        how = "trained" if panels is None else \
            f"read from {path} (trained earlier by this code on the same windows; --fresh-judges retrains)"
        if panels is None:
            panels = build(train=True)
            if path is not None:
                JC.save_panels(path, panels)
        self.style_panel, self.action_panel = panels["style"], panels["action"]
        self.short_action_panel, self.dynamics_panel = panels["short_action"], panels["dynamics"]
        log(f"{len(self.members)} style, {len(self.members)} action ({ACTION_WINDOW} frames), as many one-word "
            f"action ({self.describe()}) and {len(self.dynamics_seeds)} dynamics judges {how}, on {len(x)} real "
            f"training windows ({len(xa)} of {ACTION_WINDOW} frames) of {len(self.styles)} styles")
        return self

    @staticmethod
    def action_windows(rotations: np.ndarray, roots: np.ndarray, skeleton) -> np.ndarray:
        """What the action judges see: ``judge_windows`` of ``ACTION_WINDOW`` frames. A take
        shorter than that (held-out raises last 1.9-2.3 s) is judged once, its last frame
        held to fill the window. (The style judges' one-word windows are not padded: one
        training take of 53 frames padded to a window reshuffled their training and moved
        their figures, 92.1 -> 95.8 % on the worst judge for the default, with nothing else
        changed; MODEL_CARD.md.)"""
        rotations, roots = np.asarray(rotations), np.asarray(roots)
        if 0 < len(rotations) < ACTION_WINDOW:
            held = np.minimum(np.arange(ACTION_WINDOW), len(rotations) - 1)
            rotations, roots = rotations[held], roots[held]
        return judge_windows(rotations, roots, skeleton, window=ACTION_WINDOW)

    def describe(self) -> str:
        """The panel's members, e.g. "conv 0, conv 1, conv 2, gru 0" (design and seed)."""
        return ", ".join(f"{d} {s}" for d, s in self.members)

    def style_votes(self, windows: np.ndarray) -> np.ndarray:
        """(judges, N): each style judge's choice for each window."""
        return _votes(self.style_panel, windows)

    def action_votes(self, windows: np.ndarray) -> np.ndarray:
        """(judges, N): each action judge's choice for each of ``action_windows``."""
        return _votes(self.action_panel, windows)

    def short_action_votes(self, windows: np.ndarray) -> np.ndarray:
        """(judges, N): each one-word action judge's choice for each of ``judge_windows``."""
        return _votes(self.short_action_panel, windows)

    def dynamics_votes(self, windows: np.ndarray) -> np.ndarray:
        """(dynamics judges, N): each dynamics judge's style for each window (none: (0, N))."""
        return _votes(self.dynamics_panel, windows)

    def style_features(self, windows: np.ndarray) -> list[np.ndarray]:
        """Each style judge's pooled features of the windows (the FMD's spaces)."""
        return [j.embed(windows) for j in self.style_panel]


def _votes(panel: list[WordClassifier], windows: np.ndarray) -> np.ndarray:
    return np.array([j.predict(windows) for j in panel], dtype=int).reshape(len(panel), len(windows))


def training_motions(files: list, styles: list[str], per_style: int | None, cache_dir=None) -> list:
    chosen = []
    for s in styles:
        chosen += D.files_for_style(files, s, "train")[:per_style]
    return D.load_motions(chosen, cache_dir)
