"""The measures of one set of restyled takes (``stylecast eval``'s arithmetic over clips and
windows; ``metrics.py`` has the per-frame definitions, ``judges.py`` the classifiers): each
clip's samples (``clip_measures``), a set's summary overall or for one action
(``summarise``), the actions where some figures are worst (``worst_actions``), and where a
Frechet distance lies (``fmd_figures``)."""

from __future__ import annotations

import numpy as np

from . import metrics as M

# Ratios also read on the action where they are worst (``worst_actions``): a fault of a few
# actions hides in the overall figure. The stance lock's planted feet slid 2.2-2.8x the
# input's in the six standing actions while the multistyle model's overall slide read
# 1.21-1.32, under the 1.5 bar, for several releases (MODEL_CARD.md, "Standing feet stay
# where they landed").
# ``gait_outside``: how far a gait statistic lies outside the real target takes' range (1 inside).
# ``swing_dips_excess``: the share of swings whose ankle speed dips mid-swing, less the real
# target takes' share in the same action (``metrics.swing_dips``).
WORST_ACTION_KEYS = ("slide_ratio", "skate_ratio", "gait_outside", "swing_dips_excess")


def clip_measures(inp: np.ndarray, out: np.ndarray, roots: np.ndarray, out_roots: np.ndarray, skeleton) -> dict:
    """One take's input and output (local rotations (T, J, 4) and root paths (T, 3)) -> the
    samples of each measure of both (``metrics.py``; the feet and held joints read on the
    input's contacts and holds), for ``summarise`` to pool over takes."""
    p_in = M.world_positions(inp, roots, skeleton)
    p_out = M.world_positions(out, out_roots, skeleton)
    planted, held = M.planted(p_in), M.held(p_in)
    jerk_in, jerk_out = M.jerk(p_in), M.jerk(p_out)
    return {"jerk_in": jerk_in, "jerk_out": jerk_out,
            "slide_in": M.slide_samples(p_in, planted), "slide_out": M.slide_samples(p_out, planted),
            "skate_in": M.skate_samples(p_in), "skate_out": M.skate_samples(p_out),
            "hold_in": M.hold_samples(p_in, held), "hold_out": M.hold_samples(p_out, held),
            "step_in": M.step_heights(p_in), "step_out": M.step_heights(p_out),
            "sync": M.timing_sync(p_in, p_out), "penetration": M.floor_penetration(p_in, p_out),
            "peak_jerk_ratio": M.peak_jerk_ratio(jerk_in, jerk_out),
            "hinge_in": M.off_hinge(inp), "hinge_out": M.off_hinge(out),
            "swing_dips_in": M.swing_dips(p_in), "swing_dips_out": M.swing_dips(p_out),
            "gait_in": M.gait_statistics(inp, p_in), "gait_out": M.gait_statistics(out, p_out)}


def mean_ratio(out: np.ndarray, inp: np.ndarray) -> float:
    """Mean of ``out`` over mean of ``inp`` (samples of a measure), nan with no samples."""
    return float(out.mean() / max(inp.mean(), 1e-9)) if inp.size and out.size else float("nan")


def window_labels(windows_per_take: list, labels: list[int]) -> np.ndarray:
    """Each take's label repeated over its windows (``len`` of each entry), concatenated."""
    return np.concatenate([np.full(len(w), a) for w, a in zip(windows_per_take, labels)])


def summarise(per_clip: list[dict], windows_pred: list[np.ndarray], windows_action: list[np.ndarray],
              actions_true: list[int], target: int, styles: list[str], actions: list[str],
              windows_dynamics: list[np.ndarray] | None = None,
              windows_short_action: list[np.ndarray] | None = None) -> dict:
    """Takes' ``clip_measures`` and their windows' votes (per take, (judges, windows)) ->
    every figure of the set: each judge's share and the panel's mean for what judges read,
    output over input for the rest."""
    jin = np.concatenate([c["jerk_in"] for c in per_clip])
    jout = np.concatenate([c["jerk_out"] for c in per_clip])
    g_in, g_out = M.group_means(jin), M.group_means(jout)
    s_in = np.concatenate([c["slide_in"] for c in per_clip])
    s_out = np.concatenate([c["slide_out"] for c in per_clip])
    k_in = np.concatenate([c["skate_in"] for c in per_clip])
    k_out = np.concatenate([c["skate_out"] for c in per_clip])
    h_in = np.concatenate([c["hold_in"] for c in per_clip])
    h_out = np.concatenate([c["hold_out"] for c in per_clip])
    st_in = np.concatenate([c["step_in"] for c in per_clip])
    st_out = np.concatenate([c["step_out"] for c in per_clip])
    # Votes are (judges, windows): every figure read by the judges is given per judge and
    # as the panel's mean (report.py reads the goals on the worst judge).
    pred = np.concatenate(windows_pred, axis=1) if windows_pred else np.zeros((1, 0), int)

    def kept_by_judge(votes: list[np.ndarray] | None) -> tuple[np.ndarray, list[float]]:
        """Each judge's share of windows judged as their take's action (the action judges'
        windows and the one-word ones differ in number)."""
        if not votes:
            return np.zeros((1, 0), int), []
        act = np.concatenate(votes, axis=1)
        truth = window_labels([v.T for v in votes], actions_true)  # votes are (judges, windows)
        return act, [float(np.mean(a == truth)) for a in act] if act.shape[1] else []

    style_by_judge = [float(np.mean(p == target)) for p in pred] if pred.shape[1] else []
    act, action_by_judge = kept_by_judge(windows_action)
    _, short_action_by_judge = kept_by_judge(windows_short_action)
    dyn = np.concatenate(windows_dynamics, axis=1) if windows_dynamics else np.zeros((0, 0), int)
    dynamics_by_judge = [float(np.mean(d == target)) for d in dyn] if dyn.shape[1] else []
    sync = [c["sync"] for c in per_clip if np.isfinite(c["sync"])]
    sink = np.concatenate([c["penetration"] for c in per_clip])
    peaks = [c["peak_jerk_ratio"] for c in per_clip]
    hinge_in = np.concatenate([c["hinge_in"] for c in per_clip])
    hinge_out = np.concatenate([c["hinge_out"] for c in per_clip])
    dips_in = np.concatenate([c["swing_dips_in"] for c in per_clip])
    dips_out = np.concatenate([c["swing_dips_out"] for c in per_clip])
    return {
        "windows": int(pred.shape[1]),
        "judged_target": float(np.mean(style_by_judge)) if style_by_judge else float("nan"),
        "judged_target_judges": style_by_judge,
        "judged_as": {s: float(np.mean(pred == k)) for k, s in enumerate(styles)} if pred.shape[1] else {},
        "action_kept": float(np.mean(action_by_judge)) if action_by_judge else float("nan"),
        "action_kept_judges": action_by_judge,
        "action_kept_short": float(np.mean(short_action_by_judge)) if short_action_by_judge else float("nan"),
        "action_kept_short_judges": short_action_by_judge,
        "judged_target_dynamics": float(np.mean(dynamics_by_judge)) if dynamics_by_judge else float("nan"),
        "judged_target_dynamics_judges": dynamics_by_judge,
        "action_taken_as": {a: float(np.mean(act == k)) for k, a in enumerate(actions)} if act.shape[1] else {},
        "jerk_ratio": {g: g_out[g] / max(g_in[g], 1e-12) for g in g_in},
        "jerk_cm_per_frame3": g_out,
        "peak_jerk_ratio": float(max(peaks)) if peaks else float("nan"),  # the worst clip
        "peak_jerk_ratio_median": float(np.median(peaks)) if peaks else float("nan"),
        "slide_cm_per_frame": float(s_out.mean()) if s_out.size else float("nan"),
        "slide_input_cm_per_frame": float(s_in.mean()) if s_in.size else float("nan"),
        "slide_ratio": mean_ratio(s_out, s_in),
        "planted_frames": int(s_in.size // 2),
        "skate_cm_per_frame": float(k_out.mean()) if k_out.size else float("nan"),
        "skate_input_cm_per_frame": float(k_in.mean()) if k_in.size else float("nan"),
        "skate_ratio": mean_ratio(k_out, k_in),
        "hold_cm_per_frame": float(h_out.mean()) if h_out.size else float("nan"),
        "hold_input_cm_per_frame": float(h_in.mean()) if h_in.size else float("nan"),
        "hold_ratio": mean_ratio(h_out, h_in),
        "step_height_cm": float(st_out.mean()) if st_out.size else float("nan"),
        "step_height_input_cm": float(st_in.mean()) if st_in.size else float("nan"),
        "step_height_ratio": mean_ratio(st_out, st_in),
        "timing_sync": float(np.mean(sync)) if sync else float("nan"),
        "floor_penetration_cm": float(sink.mean()) if sink.size else float("nan"),
        "floor_penetration_p99_cm": float(np.percentile(sink, 99)) if sink.size else float("nan"),
        "off_hinge_p99_deg": float(np.percentile(hinge_out, 99)) if hinge_out.size else float("nan"),
        "off_hinge_input_p99_deg": float(np.percentile(hinge_in, 99)) if hinge_in.size else float("nan"),
        "swings": int(dips_out.size),
        "swing_dip_share": float(dips_out.mean()) if dips_out.size else float("nan"),
        "swing_dip_share_input": float(dips_in.mean()) if dips_in.size else float("nan"),
        "gait": {k: float(np.mean([c["gait_out"][k] for c in per_clip])) for k in M.GAIT_STATISTICS},
        "gait_input": {k: float(np.mean([c["gait_in"][k] for c in per_clip])) for k in M.GAIT_STATISTICS},
    }


def fmd_figures(feats: list[np.ndarray], labels: np.ndarray, feats_target: list[np.ndarray],
                target_labels: np.ndarray, actions: list[str]) -> dict:
    """Where a Frechet distance lies, per judge: windows' features ``feats`` (one (N, D) set
    per judge, actions ``labels``) against the real held-out target windows'. Overall: the
    distance, its mean part (the rest is the covariances'), and the distance with the windows
    weighted to the real set's action mix (a restyle of the normal takes inherits their mix:
    how much of the distance that alone is). Per action: ``metrics.feature_gap`` to the real
    windows of the same action (a covariance of 64+ dimensions needs more windows than one
    action has)."""
    parts = [M.frechet_parts(f, t) if len(f) > 1 else (float("nan"),) * 2 for f, t in zip(feats, feats_target)]
    weights = M.mix_weights(labels, target_labels)
    overall = {"fmd_judges": [p[0] for p in parts], "fmd_mean_part_judges": [p[1] for p in parts],
               "fmd_action_matched_judges": [M.frechet_distance(f, t, weights) if len(f) > 1 else float("nan")
                                             for f, t in zip(feats, feats_target)]}
    per_action = {actions[a]: {"feature_gap_judges": [M.feature_gap(f[labels == a], t[target_labels == a])
                                                      for f, t in zip(feats, feats_target)]}
                  for a in sorted(set(labels.tolist()) & set(target_labels.tolist()))}
    return {"overall": overall, "per_action": per_action}


def gait_outside(gait: dict, ranges: dict) -> tuple[float, str]:
    """A set's mean gait statistics (``summarise``'s ``gait``) and the real target takes'
    range of each ({name: (lowest, highest)}, the same action), each widened by its
    ``metrics.GAIT_STATISTICS`` tolerance -> how far the statistic furthest outside its
    range lies, as a factor (1 inside; 1.4: 40 % past the top, or the bottom over 1.4), and
    its name ("" inside). A figure under the range at or below 0 (feet crossed on average)
    reads 100, as far out as a figure here goes."""
    worst, name = 1.0, ""
    for k, (low, high) in ranges.items():
        v, slack = gait[k], M.GAIT_STATISTICS[k].tolerance
        low, high = low - slack, high + slack
        if v > high:
            factor = v / high
        elif v < low:
            factor = min(low / v, 100.0) if v > 0 else 100.0
        else:
            continue
        if factor > worst:
            worst, name = float(factor), k
    return worst, name


def worst_actions(per_action: dict) -> dict:
    """Per-action summaries (``summarise`` of each action's takes, by action name) -> for
    each of ``WORST_ACTION_KEYS`` with a figure, the largest of any action and which:
    {key: {"value": v, "action": name}}."""
    out = {}
    for key in WORST_ACTION_KEYS:
        figures = {a: s[key] for a, s in per_action.items() if np.isfinite(s.get(key, np.nan))}
        if figures:
            action = max(figures, key=figures.get)
            out[key] = {"value": float(figures[action]), "action": action}
            if per_action[action].get(f"{key}_of"):  # which of several figures (``gait_outside``)
                out[key]["of"] = per_action[action][f"{key}_of"]
    return out
