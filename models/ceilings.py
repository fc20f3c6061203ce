"""What a restyle that keeps something of its performer can read as the target, at best.

stylecast keeps parts of the performance on purpose: with ``--pace input`` the root's
travel, and always the timing (the generator restyles each word in place, and the
timing-sync goal asks for it). Real target-style motion does not share them: real
exhausted runs cover ground at about 0.8x the normal ones', and real exhausted waves beat
at about half a normal wave's rate. Each ceiling gives real held-out target clips the
source clips' value of one such property and judges them again: what a perfect restyle
that keeps it could read. Figures are per judge; overall on the restyled clips' action mix
(each action weighted by ``weights``, its restyled windows), over the actions both styles
have.
"""

from __future__ import annotations

import numpy as np

from stylecast.motion.clip import Clip
from stylecast.motion.resample import resample

from . import metrics as M
from .judges import judge_windows

FPS = 60.0  # the evaluation's frame rate (``data.load_motions``)


def _weighted(per_action: dict, keys: tuple[str, ...], weights: dict[str, int]) -> dict:
    """Each ``{key}_judges`` figure over the actions, weighted by ``weights``."""
    mix = {a: weights.get(a, 0) for a in per_action}
    total = sum(mix.values())
    return {f"{k}_judges": (sum(np.asarray(per_action[a][f"{k}_judges"]) * n for a, n in mix.items()) / total).tolist()
            if total else [] for k in keys}


def travel_ceiling(source_clips, target_clips, target_windows, target_k: int, judges, skeleton,
                   weights: dict[str, int]) -> dict:
    """How well a restyle that keeps the input's travel can read as the target, at best.

    With ``--pace input`` stylecast keeps the root's horizontal path (an avatar stays where
    its performer is), but the judges see a window's positions relative to the hips at its
    centre, travel included, and some styles cover ground at their own speed (real exhausted
    runs at about 0.8x the normal ones'). So real held-out target-style clips are judged
    twice: as they are,
    and with their root path covered at the mean speed of the source clips of the same action
    (``metrics.with_travel_speed``: path shape, timing and posture kept). The second is what a
    perfect restyle could read through a lock on the input's travel. Per action, and overall
    on the restyled clips' mix: each action weighted by ``weights`` (its restyled windows),
    over the actions both styles have. Figures are per judge."""
    speed = {}
    for m in source_clips:
        speed.setdefault(m.file.action, []).append(M.travel_speed(m.root_positions))
    votes: dict[str, dict[str, list]] = {}
    for m, as_is in zip(target_clips, target_windows):
        a = m.file.action
        if a not in speed:
            continue
        moved = M.with_travel_speed(m.root_positions, float(np.mean(speed[a])))
        row = votes.setdefault(a, {"as_is": [], "source_travel": [], "speed": []})
        row["as_is"].append(judges.style_votes(as_is) == target_k)
        row["source_travel"].append(judges.style_votes(judge_windows(m.rotations, moved, skeleton)) == target_k)
        row["speed"].append(M.travel_speed(m.root_positions))
    per_action = {a: {"speed_ratio": float(np.mean(v["speed"]) / max(np.mean(speed[a]), 1e-12)),
                      **{f"{k}_judges": np.concatenate(v[k], axis=1).mean(axis=1).tolist()
                         for k in ("as_is", "source_travel")}}
                  for a, v in sorted(votes.items())}
    return {"overall": _weighted(per_action, ("as_is", "source_travel"), weights), "per_action": per_action,
            "actions_missing": sorted(set(weights) - set(per_action))}


def played_at(rotations: np.ndarray, roots: np.ndarray, skeleton, speed: float) -> tuple[np.ndarray, np.ndarray]:
    """A take (rotations (T, J, 4), roots (T, 3) at 60 fps) played ``speed`` times as fast:
    resampled (slerp, lerp), so every pose is the take's and only the rate changes (the
    root's travel with it: a walk's tempo ratio is near 1, a standing action hardly travels)."""
    clip = resample(Clip(skeleton, rotations, roots, FPS), FPS / speed)
    return clip.rotations, clip.root_positions


def tempo_ceiling(source_clips, target_clips, target_k: int, judges, skeleton, feats_target: list[np.ndarray],
                  target_labels: np.ndarray, actions: list[str], weights: dict[str, int]) -> dict:
    """How well a restyle that keeps the performer's timing can read as the target, at best.

    Real held-out target clips are played at the tempo (``metrics.tempo``, the median over
    clips) of the source clips of the same action and judged: by the style judges, by the
    dynamics judges, and by the FMD of their windows (weighted to the real windows' action
    mix) to the real held-out target windows as recorded, per style judge (the report shows
    it over the floor). What is left is the distance a restyle in the performer's own time
    cannot close."""
    tempi: dict[str, dict[str, list]] = {}
    for role, clips in (("source", source_clips), ("target", target_clips)):
        for m in clips:
            positions = M.world_positions(m.rotations, m.root_positions, skeleton)
            tempi.setdefault(m.file.action, {"source": [], "target": []})[role].append(M.tempo(positions))
    rows: dict[str, dict] = {}
    feats, labels = [], []
    for m in target_clips:
        a = m.file.action
        if not tempi[a]["source"]:
            continue
        ratio = float(np.median(tempi[a]["source"]) / np.median(tempi[a]["target"]))
        windows = judge_windows(*played_at(m.rotations, m.root_positions, skeleton, ratio), skeleton)
        if not len(windows):
            continue
        row = rows.setdefault(a, {"tempo_ratio": ratio, "judged": [], "dynamics": []})
        row["judged"].append(judges.style_votes(windows) == target_k)
        row["dynamics"].append(judges.dynamics_votes(windows) == target_k)
        feats.append(judges.style_features(windows))
        labels.append(np.full(len(windows), actions.index(a)))
    per_action = {a: {"tempo_ratio": r["tempo_ratio"],
                      **{f"{k}_judges": np.concatenate(r[k], axis=1).mean(axis=1).tolist()
                         for k in ("judged", "dynamics")}}
                  for a, r in sorted(rows.items())}
    overall = _weighted(per_action, ("judged", "dynamics"), weights)
    if feats:
        labels = np.concatenate(labels)
        w = M.mix_weights(labels, target_labels)
        overall["fmd_judges"] = [M.frechet_distance(np.concatenate(f), t, w)
                                 for f, t in zip(zip(*feats), feats_target)]
    return {"overall": overall, "per_action": per_action}
