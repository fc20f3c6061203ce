"""``stylecast eval``: the instrument every restyler is judged by.

Held-out files only (the validation split of ``data.py``, by file: no window of them was
trained on). Every held-out clip of the source style is restyled towards the target
style by each variant, through the very code ``restyle`` and ``serve`` run (cutter,
seam blender, foot lock), in two settings:

* ``stream``: what ``serve`` sends, at its default hop, for a stream that has been
  running (the clip pre-rolled with its own mirrored motion, as ``restyle`` writes it);
* ``live-from-start``: ``serve`` started on the clip (its first words hold its first frame).

Variants: ``input`` (nothing done: the floor of every "kept" measure), ``posture`` (the
mean pose difference between the two styles added to the input: the cheapest possible
"style"), the first shipped model (``normal2exhausted-v1``, the figure to beat), the
coherence baseline, the model under test, and any ``--variant NAME=PATH``; and the model
under test without each stage around it (the foot lock, the correction low-pass, the
pelvis height, the style's pace), to show what each stage does, and with the other
``--feet`` than its own.

Measures (``metrics.py`` for the arithmetic, ``judges.py`` for the classifiers,
``eval_measures.py`` for a set of takes' summary; ``eval_plots.py`` draws the figures), each
overall and per action:
* style: share of windows a 7-style classifier (trained on all styles' training windows
  of world joint positions) judges as the target, and what else they were taken for;
* action kept: share of windows a 10-action classifier still gives the input's action;
* FMD: Frechet distance of the style classifier's pooled features between restyled
  windows and real held-out windows of the target style; floor = real training windows
  of the target style against the same held-out ones; where it lies (``fmd_figures``):
  its mean part, the distance at the real windows' action mix, each action's feature gap;
  (each of these three by every judge of a panel trained from different seeds: the panel's
  mean is shown, and the goals are read on its worst judge; ``judges.py`` says why)
* dynamics: share of windows judged as the target by style classifiers that see only
  velocities (a stricter goal than the issue's: a restyle of posture alone fails it);
* jerk ratio per joint group (output / input), beside the same ratio of real target-style
  clips to real source-style clips of each action;
* planted-foot slide: horizontal foot speed where the input's foot is planted (output /
  input);
* skating on the output's own contacts (``metrics.skate_samples``: feet moving while low,
  whatever the input's feet did there), output / input, stricter than the issue;
* timing sync (correlation of body speed, input vs output);
* seam ratio (METHOD.md) of the blended output, and of plain 60-frame words for contrast;
* the ceilings (``ceilings.py``): real target-style clips judged with their root path
  covered at the source clips' speed, what a restyle that keeps the input's travel
  (``--pace input``) could read at best; and played at the source clips' tempo, what one
  that keeps the performer's timing could (style, dynamics and FMD).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from stylecast.motion.errors import UserError
from stylecast.motion.footlock import AUTO_FEET, FEET, ContactSettings, feet_for
from stylecast.motion.smoothing import CORRECTION_TAU
from stylecast.motion.words import DEFAULT_HOP, WORD_LENGTH as WORD, serving_word_end, stream_settings_of

from . import data as D
from .data import bandai_skeleton
from .eval_measures import (clip_measures, fmd_figures, gait_outside, mean_ratio, summarise, window_labels,
                            worst_actions)
from .eval_plots import hand_foot_plot, style_space_plot
from . import metrics as M
from . import representation as R
from .baselines import PostureRestyler
from .ceilings import tempo_ceiling, travel_ceiling
from .judges import DYNAMICS_PANEL, PANEL, RECURRENT_PANEL, Judges, judge_windows, training_motions
from .restyle import half_rate_held, padding, restyle_rotations
from .restyler import Restyler

SHIPPED_V1 = "normal2exhausted-v1"
SHIPPED_V2 = "normal2exhausted-v2"
SHIPPED_V3 = "normal2exhausted-v3"
BASELINE = "normal2exhausted-coherence"
# (name, rendered as a stream that starts with the clip, frames dropped before measuring).
# "stream": every frame served by words, as ``serve`` sends a stream that has been running
# (the clip is pre-rolled with its own mirrored motion, as ``restyle`` does; that the
# daemon computes exactly this is tests/test_daemon.py's restyle --live == serve).
# "live-from-start": ``serve`` started on the clip itself: its first words hold the clip's
# first frame before it, and the first frame is shown restyled (``BlendSettings.start_restyled``;
# a fade-in over the first half second until 2026-11-28). The held-out takes are 2 to 9 s long
# (median 2.2 s), so a stream's start is a good part of a clip; the goals are read on "stream".
SETTINGS = (("stream", False, 0), ("live-from-start", True, 0))
# The held-out files' own rate (the Bandai BVHs, tests/test_bvh.py checks it): serve replaying
# one starts it as a half-rate stream (``restyle.half_rate_held``), and "live-from-start" with it.
LIVE_SOURCE_FPS = 30.0


@dataclass
class Variant:
    name: str
    restyle_words: object  # (B, 60, J, 4) -> (B, 60, J, 4), or None for the input itself
    note: str
    lock_feet: bool = True  # the product always locks; one row shows what the lock does
    contacts: ContactSettings = FEET["input"]  # ...with a foot lock (the model's own) and the pelvis height
    start_restyled: bool = True  # ...and a stream's first frame restyled or faded in (the model's own)
    # ...and low-passes the correction (the model's own time constant; one row shows 0, no low-pass)
    correction_tau: float = CORRECTION_TAU


# --- the paper's smoothness and the seams ----------------------------------------------------

def measure_space(quats: np.ndarray) -> np.ndarray:
    """(T, J, 4) -> (T, J, 3) the paper's units: Euler / 180, heading removed per frame."""
    flat, _ = R.remove_heading(np.asarray(quats, dtype=np.float64)[:, None])
    return R.euler_features(flat[:, 0])


def frame_differences(quats: np.ndarray) -> np.ndarray:
    """d_t per bone (METHOD.md): (T, J, 4) -> (T-1, J)."""
    return np.linalg.norm(np.diff(measure_space(quats), axis=0), axis=-1)


def switch_mask(num_frames: int, hop: int, live: bool, held_first: int = 0) -> np.ndarray:
    """(T-1,) True where frames t-1 and t are served by different words (``held_first``: a
    live stream's held copies of its first frame, ``restyle_rotations``'). A live stream's
    first words, ending before frame 59, are counted as one."""
    before = held_first if live else padding(hop)[0]
    serving = np.maximum(serving_word_end(np.arange(num_frames) + before, hop), WORD - 1)
    return serving[1:] != serving[:-1]


def seam_ratio(ds: list[np.ndarray], masks: list[np.ndarray]) -> float:
    seam = np.concatenate([d[m].ravel() for d, m in zip(ds, masks)])
    rest = np.concatenate([d[~m].ravel() for d, m in zip(ds, masks)])
    return float(seam.mean() / rest.mean()) if seam.size and rest.size else float("nan")


# --- loading ---------------------------------------------------------------------------------------

def _torch_threads() -> int:
    """The thread count the judges were trained with: it changes their float rounding, and
    so their figures (v1 read 6 points higher to judges trained at two threads than at one)."""
    import torch

    return torch.get_num_threads()


def _optional_model(name: str, log) -> Restyler | None:
    try:
        return Restyler.load(name)
    except UserError as exc:
        log(f"skipping {name}: {exc}")
        return None


def build_variants(proposed: Restyler, extra: dict[str, str], posture: PostureRestyler, log,
                   source: str | None = None) -> list[Variant]:
    source = source or proposed.eval_source
    out = [Variant("input", None, "the input itself"),
           Variant("posture", posture.restyle_words, "mean pose difference of the styles added to the input")]
    for name, note in ((SHIPPED_V1, "first shipped model (free full-rate correction, no foot lock in training)"),
                       (SHIPPED_V2, "an earlier default (smooth correction, no action-content loss)"),
                       (SHIPPED_V3, "the previous default (the action-content loss at 0.25), before `tune-holds`"),
                       (BASELINE, "Adult2Child temporal-coherence baseline")):
        r = _optional_model(name, log)  # shipped pair models, beside a pair model of the same styles
        if r is not None and r.styles == proposed.styles and r.path != proposed.path:
            out.append(Variant(name, r.for_target(proposed.target_style).restyle_words, note,
                               contacts=feet_for(AUTO_FEET, r), **stream_settings_of(r)))
    for name, path in extra.items():
        try:
            other = Restyler.load(path).for_target(proposed.target_style)
        except UserError as exc:  # a pair model beside a multi-style one: only its own target
            log(f"skipping {name} for {proposed.target_style}: {exc}")
            continue
        if not other.accepts_source(source):
            log(f"skipping {name}: it restyles {other.source_style} input, not {source}")
            continue
        other = other.with_performer_style(source)
        out.append(Variant(name, other.restyle_words, f"`{path}` ({other.name}, {other.source_style} -> "
                                                      f"{other.target_style})", contacts=feet_for(AUTO_FEET, other),
                           **stream_settings_of(other)))
    ships = stream_settings_of(proposed)  # its stream's start and correction low-pass, as it ships
    out.append(Variant("proposed-unlocked", proposed.restyle_words, "the model under test without the foot lock",
                       lock_feet=False, **ships))
    own = feet_for(AUTO_FEET, proposed)  # the foot lock it ships with (``--feet auto``)
    out.append(Variant("proposed-unsmoothed", proposed.restyle_words,
                       "the model under test without the correction low-pass", contacts=own,
                       **{**ships, "correction_tau": 0.0}))
    out.append(Variant("proposed-fixed-pelvis", proposed.restyle_words,
                       "the model under test with the root's height passed through (no pelvis height)",
                       contacts=replace(own, pelvis_tau=0), **ships))
    out.append(Variant("proposed-input-pace", proposed.restyle_words,
                       "the model under test at the input's pace (`--pace input`: the root's horizontal path passes "
                       "through)", contacts=feet_for(AUTO_FEET, proposed, "input"), **ships))
    other = next(name for name in FEET if name != proposed.feet)
    out.append(Variant(f"proposed-feet-{other}", proposed.restyle_words,
                       f"the model under test with `--feet {other}` instead of its own",
                       contacts=feet_for(other, proposed), **ships))
    out.append(Variant("proposed", proposed.restyle_words, f"`{proposed.path}` (model under test, "
                                                           f"`--feet {proposed.feet}`, `--pace style`)", contacts=own,
                       **ships))
    return out


# --- the evaluation ---------------------------------------------------------------------------------

def evaluate(model=None, out: Path | str = "runs/eval", variants: dict[str, str] | None = None,
             max_files: int | None = None, hop: int = DEFAULT_HOP, data_dir=None, cache_dir=None,
             seed: int = 0, direction: str | None = None, log=print, targets: list[str] | None = None,
             source: str | None = None, panel: int = PANEL, dynamics: int = DYNAMICS_PANEL,
             recurrent: int = RECURRENT_PANEL, fresh_judges: bool = False) -> Path:
    """Evaluate ``model`` towards each of ``targets`` (default: the model's own target; a
    multi-style model needs them named). One target: the report in ``out``; several: one
    folder per target under ``out`` and ``out/summary.md`` beside them. The judges (a panel
    of ``panel`` conv judges of each kind, seeds ``seed``, ``seed + 1``, ..., ``recurrent`` GRU
    judges of each kind, and ``dynamics`` style judges that see only velocities) are trained once
    and shared, and kept in the cache folder for the next evaluation on the same windows with
    the same code (``judge_cache``; ``fresh_judges`` trains them anew). ``source``: the style of the
    held-out clips restyled (default the model's source; normal for a multi-style model,
    which takes any)."""
    import torch

    from .styles import STYLES, check_style

    for t in [*(targets or []), *([source] if source else [])]:
        if t != "all":
            check_style(t)  # one sentence naming the known styles, before minutes of loading
    t0 = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    loaded = Restyler.load(model, direction or "a2b")
    if direction is not None and not loaded.direction:  # it would have been ignored
        raise UserError(f"--direction {direction}: model {loaded.name} has no directions; name the styles to "
                        f"measure with --target (and --source)")
    source = source or loaded.eval_source
    if not loaded.accepts_source(source):
        raise UserError(f"model {loaded.name} restyles from {loaded.eval_source} in this direction, not from {source}; "
                        f"drop --source or use --direction")
    loaded = loaded.with_performer_style(source)  # a multi-style model passes that style's share through
    if targets == ["all"]:
        targets = [s for s in STYLES if s != source]
    targets = list(targets or ([loaded.default_target] if loaded.default_target else []))
    if not targets:
        raise UserError(f"model {loaded.name} can restyle towards any style; name one or more with --target "
                        f"({', '.join(s for s in STYLES if s != source)})")
    if source in targets:
        raise UserError(f"--target {source} is the style the evaluation restyles from; choose another "
                        f"target")
    proposed = {t: loaded.for_target(t) for t in targets}  # a pair model refuses a style it lacks, here
    files = D.list_files(data_dir)
    styles, actions = D.styles_present(files), D.actions_present(files)
    skeleton = bandai_skeleton(files)

    torch.manual_seed(seed)
    per_style = None if max_files is None else 6 * max_files
    judges = Judges(styles, actions, seed, panel, dynamics, recurrent).fit(
        training_motions(files, styles, per_style, cache_dir), skeleton, log,
        cache_dir=cache_dir or D.default_cache_dir(), fresh=fresh_judges)
    held = {s: D.load_motions(D.files_for_style(files, s, "val")[:max_files], cache_dir) for s in styles}
    real = {s: [judge_windows(m.rotations, m.root_positions, skeleton) for m in held[s]] for s in styles}
    # The judges on real held-out windows of every style: how far they can be trusted.
    judge_check = {}
    for k, s in enumerate(styles):
        w = np.concatenate(real[s])
        long = [judges.action_windows(m.rotations, m.root_positions, skeleton) for m in held[s]]

        def right(votes, windows):
            truth = window_labels(windows, [actions.index(m.file.action) for m in held[s]])
            return [float(np.mean(v == truth)) for v in votes]

        judge_check[s] = {"windows": int(len(w)), "action_windows": int(sum(len(x) for x in long)),
                          "style_accuracy_judges": [float(np.mean(v == k)) for v in judges.style_votes(w)],
                          "action_accuracy_judges": right(judges.action_votes(np.concatenate(long)), long),
                          "short_action_accuracy_judges": right(judges.short_action_votes(w), real[s]),
                          "dynamics_accuracy_judges": [float(np.mean(v == k)) for v in judges.dynamics_votes(w)]}
    shared = dict(source=source, files=files, styles=styles, actions=actions, skeleton=skeleton, judges=judges, held=held,
                  real=real, judge_check=judge_check, per_style=per_style, cache_dir=cache_dir, hop=hop, log=log)
    space = style_space_plot(out, loaded, judges, real, styles)
    if len(targets) == 1:
        return _evaluate_target(proposed[targets[0]], out, variants or {}, t0, extra_plots=space, **shared)
    summary = {}
    for t in targets:
        report = _evaluate_target(proposed[t], out / t, variants or {}, time.perf_counter(), **shared)
        summary[t] = json.loads((report.parent / "metrics.json").read_text())
    from .report import write_summary

    return write_summary(out / "summary.md", str(loaded.path), summary, space, time.perf_counter() - t0)


def _evaluate_target(proposed: Restyler, out: Path, variants: dict, t0: float, *, source, files, styles, actions, skeleton,
                     judges, held, real, judge_check, per_style, cache_dir, hop, log, extra_plots=()) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    target = proposed.target_style
    target_k = styles.index(target)
    ref = _RealReference.of(target, source, files, actions, skeleton, judges, held, real, per_style, cache_dir)
    fmd_floors = ref.fmd["overall"]["fmd_judges"]
    log(f"judges checked on held-out windows; FMD floor (real {target} train vs held-out) "
        f"{', '.join(f'{f:.3f}' for f in fmd_floors)} per judge ({time.perf_counter() - t0:.0f} s)")

    clips = held[source]
    act_idx = [actions.index(m.file.action) for m in clips]
    posture = PostureRestyler.from_data(source, target, files, cache_dir, per_style)
    results: dict = {}
    outputs_for_plot: dict = {}
    for variant in build_variants(proposed, variants, posture, log, source):
        for setting, live, skip in SETTINGS:
            summary, outputs = _judge_setting(variant, clips, live, skip, hop, skeleton, judges, ref, act_idx,
                                              target_k, styles, actions)
            if setting == "stream":
                outputs_for_plot[variant.name] = outputs
            # The input's own figure on the same grid is not 1 in short clips (the seams
            # fall at the same times in every take): the goal is read relative to it.
            own = summary["overall"]["seam_ratio"]
            base = own if variant.name == "input" else results["input"][setting]["overall"]["seam_ratio"]
            summary["overall"]["seam_ratio_relative"] = own / base
            results.setdefault(variant.name, {"note": variant.note})[setting] = summary
        log(f"{variant.name}: judged {target} {100 * results[variant.name]['stream']['overall']['judged_target']:.1f} % "
            f"({time.perf_counter() - t0:.0f} s)")

    windows = {a: o["windows"] for a, o in results["input"]["stream"]["per_action"].items()}
    ceiling = travel_ceiling(held[source], held[target], real[target], target_k, judges, skeleton, windows)
    tempo = tempo_ceiling(held[source], held[target], target_k, judges, skeleton, ref.features, ref.labels, actions,
                          windows)

    # The paper's plain words (hop 60, no blend) against the blend, for the model under test.
    plain = [restyle_rotations(m.rotations.astype(np.float64), proposed.restyle_words, WORD, decay_frames=0).rotations
             for m in clips]
    plain_seam = seam_ratio([frame_differences(p) for p in plain], [switch_mask(len(p), WORD, False) for p in plain])

    metrics = {"model": str(proposed.path), "source": source, "target": target, "hop": hop,
               "held_out_files": {s: len(held[s]) for s in styles}, "judges": judge_check,
               "judge_seeds": judges.seeds, "judge_panel": judges.describe(),
               "dynamics_judge_seeds": judges.dynamics_seeds,
               "fmd_floor": float(np.mean(fmd_floors)), "fmd_floor_judges": fmd_floors,
               "fmd_floor_parts": ref.fmd,
               "real_target_jerk_ratio": ref.jerk, "real_target_hold_ratio": ref.hold,
               "real_target_skate_ratio": ref.skate, "real_target_step_ratio": ref.step,
               "real_target_gait_range": ref.gait, "real_target_swing_dip_share": ref.swing_dips,
               "travel_ceiling": ceiling, "tempo_ceiling": tempo,
               "results": results,
               "plain_words_seam_ratio": plain_seam, "seconds": time.perf_counter() - t0,
               "torch_threads": _torch_threads()}
    plots = hand_foot_plot(out, clips, outputs_for_plot, skeleton, ("input", SHIPPED_V1, "proposed"))
    plots += list(extra_plots)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2) + "\n")
    from .report import write_report

    report = write_report(out / "report.md", metrics, plots)
    log(f"eval done in {metrics['seconds']:.0f} s")
    return report


@dataclass
class _RealReference:
    """What a target's figures are read against, from real motion alone: the style judges'
    features of the real held-out target windows (per judge) and their actions, FMD between
    real training and held-out target windows (the floor), and the jerk, holds, skating and
    step height of real target-style clips over real source-style clips of the same action,
    per action (a take's own holds: real motion has no input to hold still against); and
    the range of each gait statistic over every real target-style take of each action,
    training and held-out (``gait``: {action: {name: (lowest, highest)}}: what any real
    performer of the style did), and the share of those takes' swings whose ankle speed
    dips mid-swing (``swing_dips``: {action: share}, where they have swings)."""

    features: list
    labels: np.ndarray
    fmd: dict
    jerk: dict
    hold: dict
    skate: dict
    step: dict
    gait: dict
    swing_dips: dict

    @classmethod
    def of(cls, target, source, files, actions, skeleton, judges, held, real, per_style, cache_dir) -> "_RealReference":
        target_train = training_motions(files, [target], per_style, cache_dir)
        train_takes = [judge_windows(m.rotations, m.root_positions, skeleton) for m in target_train]
        features = judges.style_features(np.concatenate(real[target]))
        labels = window_labels(real[target], [actions.index(m.file.action) for m in held[target]])
        train_labels = window_labels(train_takes, [actions.index(m.file.action) for m in target_train])
        fmd = fmd_figures(judges.style_features(np.concatenate(train_takes)), train_labels, features, labels, actions)
        jerk, hold, skate, step = {}, {}, {}, {}
        for a in actions:
            pos = {s: [M.world_positions(m.rotations, m.root_positions, skeleton)
                       for m in held[s] if m.file.action == a] for s in (source, target)}
            if pos[source] and pos[target]:
                j = {s: np.concatenate([M.jerk(p) for p in pos[s]]) for s in pos}
                gs, gt = M.group_means(j[source]), M.group_means(j[target])
                jerk[a] = {g: gt[g] / max(gs[g], 1e-12) for g in gs}
                h = {s: np.concatenate([M.hold_samples(p, M.held(p)) for p in pos[s]]) for s in pos}
                hold[a] = mean_ratio(h[target], h[source])
                k = {s: np.concatenate([M.skate_samples(p) for p in pos[s]]) for s in pos}
                skate[a] = mean_ratio(k[target], k[source])
                st = {s: np.concatenate([M.step_heights(p) for p in pos[s]]) for s in pos}
                step[a] = mean_ratio(st[target], st[source])
        gait, swing_dips = {}, {}
        for a in actions:
            motions = [m for m in target_train + held[target] if m.file.action == a]
            pos = [M.world_positions(m.rotations, m.root_positions, skeleton) for m in motions]
            if motions:
                takes = [M.gait_statistics(m.rotations, p) for m, p in zip(motions, pos)]
                gait[a] = {k: (min(t[k] for t in takes), max(t[k] for t in takes)) for k in M.GAIT_STATISTICS}
            dips = np.concatenate([M.swing_dips(p) for p in pos]) if pos else np.zeros(0)
            if dips.size:
                swing_dips[a] = float(dips.mean())
        return cls(features, labels, fmd, jerk, hold, skate, step, gait, swing_dips)


def _judge_setting(variant: Variant, clips: list, live: bool, skip: int, hop: int, skeleton, judges,
                   ref: _RealReference, act_idx: list[int], target_k: int, styles, actions) -> tuple[dict, list]:
    """One variant's restyle of every clip in one setting (the running stream, or live from
    a take's start), judged and measured: its summary (overall and per action, FMD against
    the real target windows, the seam ratio) and the restyled (rotations, roots) per clip."""
    held_first = half_rate_held(LIVE_SOURCE_FPS, hop) if live else 0
    per_clip, preds, acts, short_acts, dyns, feats, ds, masks, outputs = [], [], [], [], [], [], [], [], []
    for m in clips:
        inp = m.rotations.astype(np.float64)
        roots = m.root_positions.astype(np.float64)
        out_roots = roots
        if variant.restyle_words is None:
            res = inp
        else:
            lock = dict(roots=roots, skeleton=skeleton) if variant.lock_feet else {}
            res, moved = restyle_rotations(inp, variant.restyle_words, hop, live=live,
                                           correction_tau=variant.correction_tau,
                                           start_restyled=variant.start_restyled,
                                           contacts=variant.contacts, held_first=held_first, **lock)
            out_roots = roots if moved is None else moved  # the pelvis height the lock set
        mask = switch_mask(len(res), hop, live, held_first)[skip:]
        inp, res, roots, out_roots = inp[skip:], res[skip:], roots[skip:], out_roots[skip:]
        per_clip.append(clip_measures(inp, res, roots, out_roots, skeleton))
        w = judge_windows(res, out_roots, skeleton)
        preds.append(judges.style_votes(w))
        acts.append(judges.action_votes(judges.action_windows(res, out_roots, skeleton)))
        short_acts.append(judges.short_action_votes(w))
        dyns.append(judges.dynamics_votes(w))
        feats.append(judges.style_features(w))
        ds.append(frame_differences(res))
        masks.append(mask)
        outputs.append((res, out_roots))
    summary = {"overall": summarise(per_clip, preds, acts, act_idx, target_k, styles, actions, dyns, short_acts),
               "per_action": {}}
    for a in sorted(set(act_idx)):
        sel = [i for i, x in enumerate(act_idx) if x == a]
        summary["per_action"][actions[a]] = summarise([per_clip[i] for i in sel], [preds[i] for i in sel],
                                                      [acts[i] for i in sel], [a] * len(sel), target_k, styles,
                                                      actions, [dyns[i] for i in sel],
                                                      [short_acts[i] for i in sel])
    for a, figures in summary["per_action"].items():
        if a in ref.gait:
            figures["gait_outside"], figures["gait_outside_of"] = gait_outside(figures["gait"], ref.gait[a])
        if a in ref.swing_dips and figures["swings"]:
            figures["swing_dips_excess"] = figures["swing_dip_share"] - ref.swing_dips[a]
    summary["overall"]["worst_action"] = worst_actions(summary["per_action"])
    fmd = fmd_figures([np.concatenate(per_judge) for per_judge in zip(*feats)],
                      window_labels([f[0] for f in feats], act_idx), ref.features, ref.labels, actions)
    summary["overall"].update(fmd["overall"])
    summary["overall"]["fmd"] = float(np.mean(fmd["overall"]["fmd_judges"]))
    for a, gap in fmd["per_action"].items():
        summary["per_action"][a].update(gap)
    summary["overall"]["seam_ratio"] = seam_ratio(ds, masks)
    return summary, outputs
