"""The figures of ``stylecast eval``'s report: a hand and a foot against the input's for one
walk (``hand_foot_plot``), and the style space (``style_space_plot``: the model's style codes
and the style judge's features of real windows, each in a 2-D PCA, ``pca_2d``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from stylecast.motion.humanoid import HUMANOID_BONES

from . import data as D
from . import metrics as M


def hand_foot_plot(out: Path, clips, outputs: dict, skeleton, shown: tuple[str, ...]) -> list[str]:
    """A hand and a foot, input against the ``shown`` outputs (names in ``outputs``, the
    first the input), for one walk."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    walks = [i for i, m in enumerate(clips) if m.file.action == "walk"] or [0]
    i = walks[0]
    picked = {k: outputs[k][i] for k in shown if k in outputs}
    hand, foot = HUMANOID_BONES.index("RightHand"), HUMANOID_BONES.index("LeftFoot")
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    colours = dict(zip(shown, ("0.4", "tab:red", "tab:green", "tab:blue")))
    for name, (rotations, roots) in picked.items():
        p = M.world_positions(rotations, roots, skeleton)
        t = np.arange(len(p)) / D.FPS
        axes[0].plot(t, p[:, hand, 1], color=colours[name], lw=0.9, label=name)
        axes[1].plot(t, p[:, foot, 1], color=colours[name], lw=0.9, label=name)
        axes[2].plot(t[1:], M.horizontal_speed(p, "LeftFoot"), color=colours[name], lw=0.9, label=name)
    axes[0].set_ylabel("right hand height (cm)")
    axes[1].set_ylabel("left ankle height (cm)")
    axes[2].set_ylabel("left ankle horizontal\nspeed (cm/frame)")
    axes[2].set_xlabel("seconds")
    axes[0].legend(fontsize=7)
    axes[0].set_title(f"{clips[i].file.name}, stream (as restyle writes it)", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "fig_hand_foot.png", dpi=90)
    plt.close(fig)
    return ["fig_hand_foot.png"]


def pca_2d(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows of ``x`` projected on their first two principal axes, and the share of the
    variance each axis carries."""
    c = np.asarray(x, np.float64) - np.mean(x, axis=0)
    _, sv, vt = np.linalg.svd(c, full_matrices=False)
    var = sv ** 2 / max(np.sum(sv ** 2), 1e-12)
    return c @ vt[:2].T, var[:2]


def style_space_plot(out: Path, model, judges, real: dict, styles: list[str], per_style: int = 200) -> list[str]:
    """The style space as a PNG: the model's style codes (when it has them) and the style
    judge's pooled features of real held-out windows, each in its own 2-D PCA."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    codes = getattr(model, "style_codes", None)  # multi-style models only
    fig, axes = plt.subplots(1, 2 if codes else 1, figsize=(11 if codes else 6, 5), squeeze=False)
    axes = axes[0]
    colours = plt.get_cmap("tab10")
    emb, lab = [], []
    for k, s in enumerate(styles):
        w = np.concatenate(real[s])
        pick = np.linspace(0, len(w) - 1, min(per_style, len(w))).astype(int)
        emb.append(judges.style.embed(w[pick]))
        lab.append(np.full(len(pick), k))
    xy, var = pca_2d(np.concatenate(emb))
    lab = np.concatenate(lab)
    ax = axes[-1]
    for k, s in enumerate(styles):
        ax.scatter(*xy[lab == k].T, s=6, alpha=0.5, color=colours(k), label=s)
    ax.set_title(f"real held-out windows, style judge's features\n(PCA: {100 * var[0]:.0f} % + {100 * var[1]:.0f} % of the variance)",
                 fontsize=9)
    ax.legend(fontsize=7, markerscale=2)
    if codes:
        table = codes()
        cxy, cvar = pca_2d(table)
        names = list(model.styles)
        for k, s in enumerate(names):
            axes[0].scatter(*cxy[k], s=60, color=colours(styles.index(s) if s in styles else k))
            axes[0].annotate(s, cxy[k], fontsize=8, xytext=(4, 4), textcoords="offset points")
        axes[0].set_title(f"{model.name}: the {len(names)} style codes\n(PCA: {100 * cvar[0]:.0f} % + "
                          f"{100 * cvar[1]:.0f} % of the variance)", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "fig_style_space.png", dpi=90)
    plt.close(fig)
    return ["fig_style_space.png"]
