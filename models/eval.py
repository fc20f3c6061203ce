"""``stylecast eval``: the proposed model against the baseline and the input, on held-out
files (the validation split of ``data.py``; no word of these files was trained on).

Measuring space: every metric of METHOD.md is taken on normalised Euler angles of the
humanoid bones, i.e. the paper's representation (XZY Euler angles of each bone's T-pose
relative local rotation, / 180; centred on the proposed model's reference pose if it has
one), with the Hips' heading (yaw) removed frame by frame, so a performer turning around
does not count as motion. Input, baseline and proposed are all measured in this one
space, whatever representation a model uses internally.

What is reported (section letters as in the issue):
(a) Table 3: per bone, the sum of d_t = |angles_t - angles_{t-1}| over the 59 frame pairs
    of each 60-frame window, averaged over all windows; mean and total over bones. For
    the independent words of the paper (hop 60, no blend) and the blended stream (hop 20).
(b) Figures 8-9: |d_t - d_{t-1}| per bone over the first 3 s of one held-out clip.
(c) Seam ratio: mean d_t over frame pairs where the serving word changes / mean d_t
    elsewhere, for the blended output and for plain concatenated words (hop 60).
(d) Style: a classifier trained on real training windows of both styles; its accuracy on
    real held-out windows, then the share of restyled windows it judges as the target.
(e) Content: an action classifier (10 actions) trained the same way; accuracy on held-out
    real windows and on the restyled ones; and the geodesic angle between input and output.
(f) Cycle: G_b2a(G_a2b(a)) against a (and b through the other way): mean geodesic angle.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from stylecast.motion import rotations as rot
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import HUMANOID_BONES

from . import data as D
from . import representation as R
from .classifier import WordClassifier
from .restyle import restyle_rotations, word_switches
from .restyler import Restyler

WORD = 60
PLOT_SECONDS = 3.0
LOCAL = 5  # frames either side of a seam for the local seam ratio


# --- measuring space ----------------------------------------------------------------------

def measure_space(quats: np.ndarray, reference: np.ndarray | None) -> np.ndarray:
    """(T, J, 4) -> (T, J, 3) normalised Euler angles, heading removed per frame."""
    q = np.asarray(quats, dtype=np.float64)
    flat, _ = R.remove_heading(q[:, None])  # every frame is its own one-frame "word"
    return R.euler_features(flat[:, 0], reference)


def frame_differences(features: np.ndarray) -> np.ndarray:
    """d_t per bone: (T, J, 3) -> (T-1, J)."""
    return np.linalg.norm(np.diff(features, axis=0), axis=-1)


def window_sums(d: np.ndarray, length: int = WORD) -> np.ndarray:
    """Per-window per-bone sums of d_t over complete non-overlapping windows: (W, J)."""
    n = (len(d) + 1) // length
    if n == 0:
        return np.zeros((0, d.shape[1]))
    starts = np.arange(n) * length
    return np.stack([d[s:s + length - 1].sum(axis=0) for s in starts])


def table3(ds: list[np.ndarray]) -> dict:
    sums = np.concatenate([window_sums(d) for d in ds])
    per_bone = sums.mean(axis=0)
    # METHOD.md's "mean over bones" of the per-word sum, and a per-frame reading of it.
    return {"per_bone": per_bone.tolist(), "mean": float(per_bone.mean()), "total": float(per_bone.sum()),
            "per_frame_mean": float(per_bone.mean() / (WORD - 1)), "windows": int(len(sums))}


def seam_ratio(ds: list[np.ndarray], hop: int, local: int | None = None) -> float:
    """METHOD.md's seam ratio: mean d_t over frame pairs where the serving word changes,
    divided by mean d_t over all other pairs. With ``local=k`` the denominator is only the
    pairs within k frames of a seam: the same idea, but insensitive to where in a clip the
    seams fall (in short clips the global ratio also measures that the middle of a clip
    moves faster than its ends, which is no seam)."""
    seam, rest = [], []
    for d in ds:
        m = word_switches(len(d) + 1, hop)
        if local:
            near = np.zeros_like(m)
            for k in range(1, local + 1):
                near[k:] |= m[:-k]
                near[:-k] |= m[k:]
            other = near & ~m
        else:
            other = ~m
        seam.append(d[m])
        rest.append(d[other])
    seam_v, rest_v = np.concatenate(seam), np.concatenate(rest)
    if seam_v.size == 0 or rest_v.size == 0:
        return float("nan")
    return float(seam_v.mean() / rest_v.mean())


def windows(quats: np.ndarray, length: int = WORD, hop: int = WORD) -> np.ndarray:
    return D.cut_words(np.asarray(quats), hop, length)


def window_features(words: np.ndarray, reference) -> np.ndarray:
    """Classifier input: the model's view of a word (heading removed at its centre)."""
    if len(words) == 0:
        return np.zeros((0, WORD, len(HUMANOID_BONES), 3), np.float32)
    return R.euler_features(D.headless(words), reference)


# --- the evaluation -----------------------------------------------------------------------

def _load_restyler(name, role: str) -> Restyler | None:
    try:
        return Restyler.load(name)
    except UserError:
        if role == "baseline":
            return None
        raise


def evaluate(model=None, baseline="normal2exhausted-coherence", out: Path | str = "runs/eval", max_files=None,
             hop: int = 20, data_dir=None, cache_dir=None, seed: int = 0, log=print) -> Path:
    import torch

    t0 = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    proposed = Restyler.load(model)
    base = _load_restyler(baseline, "baseline")
    if base is not None and base.styles != proposed.styles:
        raise UserError(f"the baseline translates {base.styles} but the model {proposed.styles}; pass a baseline "
                        f"trained on the same pair of styles")
    a, b = proposed.styles["a"], proposed.styles["b"]
    reference = proposed.rep.reference
    files = D.list_files(data_dir)
    val = {s: D.files_for_style(files, s, "val")[:max_files] for s in (a, b)}
    # A quick run (--max-files) also trains its classifiers on fewer files.
    train = {s: D.files_for_style(files, s, "train")[:None if max_files is None else 6 * max_files] for s in (a, b)}
    actions = D.actions_present(files)
    log(f"eval {proposed.name} vs {base.name if base else 'no baseline'}: held-out files {a} {len(val[a])}, "
        f"{b} {len(val[b])}")

    # (d), (e): measuring instruments trained on real training windows of both styles
    torch.manual_seed(seed)
    train_x, train_style, train_action = [], [], []
    for k, s in enumerate((a, b)):
        ws = D.build_wordset(D.load_motions(train[s], cache_dir), s, hop=20)
        train_x.append(R.euler_features(ws.words, reference))
        train_style.append(np.full(len(ws), k))
        train_action.append(np.array([actions.index(ws.files[i].action) for i in ws.file_index]))
    train_x = np.concatenate(train_x)
    train_style = np.concatenate(train_style)
    style_clf = WordClassifier([a, b], train_x.shape[2] * 3, seed).fit(train_x, train_style)
    # A second judge that sees only velocities: a restyle that only shifted the posture
    # could fool the first one; this one needs the dynamics to change too.
    dyn_clf = WordClassifier([a, b], train_x.shape[2] * 3, seed, velocity_only=True).fit(train_x, train_style)
    action_clf = WordClassifier(actions, train_x.shape[2] * 3, seed).fit(train_x, np.concatenate(train_action))
    log(f"classifiers trained on {len(train_x)} windows ({time.perf_counter() - t0:.0f} s)")

    held = {s: D.load_motions(val[s], cache_dir) for s in (a, b)}
    real_x, real_style, real_action = [], [], []
    for k, s in enumerate((a, b)):
        for m in held[s]:
            w = window_features(windows(m.rotations), reference)
            real_x.append(w)
            real_style.append(np.full(len(w), k))
            real_action.append(np.full(len(w), actions.index(m.file.action)))
    real_x, real_style, real_action = map(np.concatenate, (real_x, real_style, real_action))
    metrics: dict = {
        "styles": {"a": a, "b": b}, "held_out_files": {a: len(val[a]), b: len(val[b])},
        "style_classifier": {"real_heldout_accuracy": style_clf.accuracy(real_x, real_style),
                             "real_heldout_windows": int(len(real_x)),
                             "real_heldout_accuracy_per_style": {
                                 s: style_clf.accuracy(real_x[real_style == k], real_style[real_style == k])
                                 for k, s in enumerate((a, b))}},
        "dynamics_style_classifier": {"real_heldout_accuracy": dyn_clf.accuracy(real_x, real_style)},
        "action_classifier": {"real_heldout_accuracy": action_clf.accuracy(real_x, real_action)},
    }

    # restyle every held-out clip of style A: blended (hop) and plain words (hop 60, no blend)
    variants = {"proposed": proposed} | ({"baseline": base} if base is not None else {})
    clips = [m.rotations.astype(np.float64) for m in held[a]]
    outputs: dict[str, list[np.ndarray]] = {"input": clips}
    for name, r in variants.items():
        outputs[f"{name}-blend"] = [restyle_rotations(c, r.restyle_words, hop) for c in clips]
        outputs[f"{name}-words"] = [restyle_rotations(c, r.restyle_words, WORD, decay_frames=0) for c in clips]
    log(f"restyled {len(clips)} clips ({time.perf_counter() - t0:.0f} s)")

    feats = {k: [measure_space(c, reference) for c in v] for k, v in outputs.items()}
    ds = {k: [frame_differences(f) for f in v] for k, v in feats.items()}
    src_actions = [actions.index(m.file.action) for m in held[a]]
    rows = {}
    for k in outputs:
        row = {"table3": table3(ds[k])}
        row["smoothness_ratio"] = row["table3"]["mean"] / table3(ds["input"])["mean"]
        if k == "input":
            row["seam_ratio_hop"] = seam_ratio(ds[k], hop)
            row["seam_ratio_hop60"] = seam_ratio(ds[k], WORD)
            row["seam_ratio_local_hop"] = seam_ratio(ds[k], hop, LOCAL)
            row["seam_ratio_local_hop60"] = seam_ratio(ds[k], WORD, LOCAL)
        else:
            grid = hop if k.endswith("blend") else WORD
            row["seam_ratio"] = seam_ratio(ds[k], grid)
            row["seam_ratio_local"] = seam_ratio(ds[k], grid, LOCAL)
            row["seam_ratio_relative"] = row["seam_ratio"] / rows["input"]["seam_ratio_hop" if grid == hop else
                                                                          "seam_ratio_hop60"]
            geo = np.concatenate([rot.angle_between(o, c) for o, c in zip(outputs[k], clips)])  # (sumT, J)
            row["geodesic_to_input_deg"] = {"mean": float(geo.mean()), "per_bone": geo.mean(axis=0).tolist()}
        wx = [window_features(windows(c), reference) for c in outputs[k]]
        wa = np.concatenate([np.full(len(w), act) for w, act in zip(wx, src_actions)])
        wx = np.concatenate(wx)
        row["judged_target"] = float(np.mean(style_clf.predict(wx) == 1)) if len(wx) else float("nan")
        row["judged_target_dynamics"] = float(np.mean(dyn_clf.predict(wx) == 1)) if len(wx) else float("nan")
        pred = action_clf.predict(wx)
        row["action_preserved"] = float(np.mean(pred == wa)) if len(wx) else float("nan")
        wrong = [(actions[t], actions[p]) for t, p in zip(wa, pred) if t != p]
        row["action_confusions"] = [[t, p, wrong.count((t, p))] for t, p in sorted(set(wrong), key=wrong.count,
                                                                                     reverse=True)[:5]]
        row["windows"] = int(len(wx))
        rows[k] = row
    metrics["results"] = rows

    # (f) cycle reconstruction on held-out words of both styles (hop 60)
    cyc = {}
    for name, r in variants.items():
        entry = {}
        for s, fwd, back in ((a, "a2b", "b2a"), (b, "b2a", "a2b")):
            w = np.concatenate([windows(m.rotations.astype(np.float64)) for m in held[s]])
            rec = r.restyle_words(r.restyle_words(w, fwd), back)
            f_in, f_rec = window_features(w, reference), window_features(rec, reference)
            entry[s] = {"geodesic_deg": float(rot.angle_between(rec, w).mean()),
                        "l1_normalised": float(np.abs(f_rec - f_in).mean())}
        cyc[name] = entry
    metrics["cycle"] = cyc
    metrics["seconds"] = time.perf_counter() - t0
    metrics["models"] = {k: str(v.path) for k, v in variants.items()}

    plots = _plots(out, outputs, feats, ds, held[a], hop)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2) + "\n")
    report = out / "report.md"
    report.write_text(_report(metrics, plots, proposed, base, hop))
    log(f"eval done in {metrics['seconds']:.0f} s")
    return report


# --- plots and report ------------------------------------------------------------------------

def _plots(out: Path, outputs, feats, ds, motions, hop: int) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = int(PLOT_SECONDS * D.FPS)
    pick = max(range(len(motions)), key=lambda i: min(motions[i].num_frames, n) * 1000 - i)
    name = motions[pick].file.name
    curves = {k: np.abs(np.diff(ds[k][pick][:n], axis=0)) for k in ("input", "baseline-words", "proposed-words",
                                                                    "baseline-blend", "proposed-blend") if k in ds}
    files = []
    for part, bones in (("bones_00-10", range(0, 11)), ("bones_11-21", range(11, 22))):
        fig, axes = plt.subplots(len(bones), 1, figsize=(9, 1.5 * len(bones)), sharex=True)
        for ax, j in zip(axes, bones):
            for k, style in (("input", dict(color="0.5", lw=0.8)), ("baseline-words", dict(color="tab:blue", lw=0.8)),
                             ("proposed-words", dict(color="tab:orange", lw=0.8))):
                if k in curves:
                    t = (np.arange(len(curves[k])) + 2) / D.FPS
                    ax.plot(t, curves[k][:, j], label=k.replace("-words", ""), **style)
            ax.set_ylabel(f"{j} {HUMANOID_BONES[j]}", rotation=0, ha="right", fontsize=7)
            ax.tick_params(labelsize=6)
        axes[0].legend(fontsize=7, loc="upper right", ncol=3)
        axes[0].set_title(f"|d_t - d_(t-1)| per bone, first {PLOT_SECONDS:g} s of {name} (independent words)", fontsize=8)
        axes[-1].set_xlabel("seconds")
        fig.tight_layout()
        f = f"fig_{part}.png"
        fig.savefig(out / f, dpi=90)
        plt.close(fig)
        files.append(f)
    # the seam: mean d_t over bones, plain words against the blend
    fig, ax = plt.subplots(figsize=(9, 3))
    longest = max(range(len(motions)), key=lambda i: motions[i].num_frames)
    m = min(motions[longest].num_frames, 360)
    for k, c in (("input", "0.5"), ("proposed-words", "tab:red"), ("proposed-blend", "tab:green")):
        if k in ds:
            ax.plot(np.arange(1, m) / D.FPS, ds[k][longest][: m - 1].mean(axis=1), color=c, lw=0.9, label=k)
    seams = np.nonzero(word_switches(m, 60))[0] + 1
    for s in seams:
        ax.axvline(s / D.FPS, color="tab:red", ls=":", lw=0.6)
    ax.set_xlabel("seconds")
    ax.set_ylabel("mean d_t over bones")
    ax.set_title(f"word seams (dotted: hop-60 word boundaries), {motions[longest].file.name}", fontsize=8)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "fig_seams.png", dpi=90)
    plt.close(fig)
    files.append("fig_seams.png")
    return files


def _fmt(v, digits=4):
    return "n/a" if v is None or (isinstance(v, float) and np.isnan(v)) else f"{v:.{digits}f}"


def _report(m: dict, plots: list[str], proposed: Restyler, base: Restyler | None, hop: int) -> str:
    a, b = m["styles"]["a"], m["styles"]["b"]
    res = m["results"]
    lines = [f"# stylecast evaluation: {a} -> {b}", "",
             f"Proposed: `{m['models']['proposed']}` (loss {proposed.metadata.get('loss')}); baseline: "
             f"`{m['models'].get('baseline', 'none')}`. Held-out files (validation split by file, never trained on): "
             f"{m['held_out_files'][a]} {a}, {m['held_out_files'][b]} {b}. Measured in normalised Euler units "
             f"(XZY Euler angles / 180 of each bone's T-pose-relative rotation, Hips heading removed per frame).", "",
             "## (a) Table 3: frame-to-frame difference per word", "",
             "Per bone: sum of d_t over a 60-frame word, averaged over words; mean and total over the 22 bones. "
             "`words` = independent 60-frame words as in the paper (hop 60, no blending); `blend` = the "
             f"stream output (hop {hop}, seam blending) cut into 60-frame windows. Ratio = mean / input's mean "
             "(paper: proposed 1.32, baseline 2.26; goal proposed <= 1.35 and below the baseline).", "",
             "| output | mean per bone | total over bones | ratio to input | per frame per bone |",
             "|---|---|---|---|---|"]
    for k, r in res.items():
        t = r["table3"]
        lines.append(f"| {k} | {_fmt(t['mean'])} | {_fmt(t['total'])} | {_fmt(r['smoothness_ratio'], 3)} | "
                     f"{_fmt(t['per_frame_mean'], 5)} |")
    lines += ["", "Per bone (words):", "", "| bone | input | " + " | ".join(k for k in res if k != "input") + " |",
              "|---|---|" + "---|" * (len(res) - 1)]
    for j, bone in enumerate(HUMANOID_BONES):
        lines.append(f"| {j} {bone} | " + " | ".join(_fmt(r["table3"]["per_bone"][j]) for r in res.values()) + " |")
    lines += ["", "## (b) Per-bone |d_t - d_(t-1)| over the first 3 s (paper's Figures 8-9)", ""]
    lines += [f"![{p}]({p})" for p in plots]
    inp = res["input"]
    lines += ["", "## (c) Seam ratio", "",
              "Mean d_t at frame pairs where the serving word changes, over mean d_t elsewhere (1.0 = no seam; "
              "goal for the blended output <= 1.10). On the hop-60 grid the seams of every clip fall at the same "
              "times (1 s, 2 s, ...), and in these short takes the motion there is not typical, so even the "
              "input's figure departs from 1. Two readings remove that bias: `relative` divides by the input's "
              f"figure on the same grid; `local` compares with the pairs within {LOCAL} frames of each seam.", "",
              "| output | seam ratio (METHOD.md) | relative to input | local seam ratio |", "|---|---|---|---|",
              f"| input (hop-{hop} grid) | {_fmt(inp['seam_ratio_hop'], 3)} | 1 | {_fmt(inp['seam_ratio_local_hop'], 3)} |",
              f"| input (hop-60 grid) | {_fmt(inp['seam_ratio_hop60'], 3)} | 1 | {_fmt(inp['seam_ratio_local_hop60'], 3)} |"]
    for k, r in res.items():
        if k != "input":
            lines.append(f"| {k} | {_fmt(r['seam_ratio'], 3)} | {_fmt(r['seam_ratio_relative'], 3)} | "
                         f"{_fmt(r['seam_ratio_local'], 3)} |")
    sc = m["style_classifier"]
    lines += ["", "## (d) Style", "",
              f"Classifier ({a} vs {b}, 1-D conv on poses and velocities) trained on real training-split windows; "
              f"accuracy on {sc['real_heldout_windows']} real held-out windows (hop 60): "
              f"**{100 * sc['real_heldout_accuracy']:.1f} %** "
              + ", ".join(f"{s} {100 * v:.1f} %" for s, v in sc["real_heldout_accuracy_per_style"].items())
              + f" (goal >= 95 %). A second classifier sees only velocities (no poses), so a restyle that "
              f"merely shifts the posture cannot fool it; its held-out accuracy is "
              f"{100 * m['dynamics_style_classifier']['real_heldout_accuracy']:.1f} %. Share of windows judged {b} "
              f"(goal for restyled >= 80 %):", "",
              "| output | judged target | judged target (velocities only) | windows |", "|---|---|---|---|"]
    for k, r in res.items():
        lines.append(f"| {k} | {100 * r['judged_target']:.1f} % | {100 * r['judged_target_dynamics']:.1f} % | "
                     f"{r['windows']} |")
    lines += ["", "## (e) Content preservation", "",
              f"Action classifier (10 actions, same training windows): accuracy on real held-out windows "
              f"{100 * m['action_classifier']['real_heldout_accuracy']:.1f} %. On restyled windows, the share still "
              f"classified as the input's action; and the mean geodesic angle between output and input rotations.", "",
              "| output | action preserved | geodesic to input (deg) |", "|---|---|---|"]
    for k, r in res.items():
        geo = r.get("geodesic_to_input_deg", {}).get("mean")
        lines.append(f"| {k} | {100 * r['action_preserved']:.1f} % | {_fmt(geo, 2) if geo is not None else '0'} |")
    lines += ["", "Most frequent confusions (input action -> predicted, windows):", ""]
    for k, r in res.items():
        conf = ", ".join(f"{t} -> {p} ({n})" for t, p, n in r["action_confusions"]) or "none"
        lines.append(f"* {k}: {conf}")
    lines += ["", "## (f) Cycle reconstruction", "",
              "Held-out words (hop 60) through both generators and back: mean geodesic angle to the original "
              "(degrees) and mean absolute difference in normalised units.", "",
              f"| model | {a}->{b}->{a} deg | L1 | {b}->{a}->{b} deg | L1 |", "|---|---|---|---|---|"]
    for name, e in m["cycle"].items():
        lines.append(f"| {name} | {_fmt(e[a]['geodesic_deg'], 2)} | {_fmt(e[a]['l1_normalised'], 5)} | "
                     f"{_fmt(e[b]['geodesic_deg'], 2)} | {_fmt(e[b]['l1_normalised'], 5)} |")
    lines += ["", f"Evaluation took {m['seconds']:.0f} s. Raw numbers: `metrics.json`.", ""]
    return "\n".join(lines)
