"""The `stylecast train`, `restyle` and `eval` commands end to end (shared Bandai data;
skipped when it is absent)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from stylecast.cli import main
from stylecast.motion import Clip, Skeleton
from stylecast.motion.bvh import read_bvh, write_bvh
from stylecast.motion.clip import forward_kinematics

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bandai"
DATA2 = SHARED / "dataset-2" / "data"
CLIP = DATA2 / "dataset-2_walk_normal_001.bvh.gz"
needs_data = pytest.mark.skipif(not CLIP.exists(), reason=f"the shared Bandai data is not at {SHARED}")


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> Path:
    """The CI training run: a few words, one epoch, through the real command."""
    if not CLIP.exists():
        pytest.skip("shared Bandai data absent")
    out = tmp_path_factory.mktemp("run")
    code = main(["train", "--max-words", "16", "--epochs", "1", "--batch-size", "4", "--words-per-epoch", "8",
                 "--threads", "1", "--seed", "1", "--out", str(out), "--no-progress"])
    assert code == 0
    return out


@needs_data
def test_train_cli_writes_a_model_and_one_csv_row(tiny_run):
    rows = (tiny_run / "losses.csv").read_text().strip().splitlines()
    assert len(rows) == 2 and rows[1].startswith("1,")
    assert (tiny_run / "model.safetensors").stat().st_size < 5_000_000


def test_train_cli_rejects_an_unknown_style_before_reading_any_data(tmp_path, capsys):
    # An empty data folder: the name is refused before the minutes of loading, or the
    # complaint would be about the data.
    (tmp_path / "empty").mkdir()
    assert main(["train", "--style-b", "sleepy", "--data", str(tmp_path / "empty"), "--out", str(tmp_path / "run"),
                 "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "unknown style 'sleepy'" in err and "exhausted" in err and "Traceback" not in err


@needs_data
def test_a_checkpoint_names_the_foot_lock_it_is_served_with(tiny_run, tmp_path, capsys):
    """``train --feet`` records the lock ``--feet auto`` then takes; without it a pair model
    takes the input's feet; a lock this stylecast does not know is refused in one sentence."""
    from stylecast.models import checkpoint as ckpt
    from stylecast.models.restyler import Restyler
    from stylecast.motion.footlock import AUTO_FEET, FEET, feet_for

    assert Restyler.load(str(tiny_run / "model.safetensors")).feet == "input"
    assert main(["train", "--max-words", "8", "--epochs", "1", "--batch-size", "4", "--words-per-epoch", "4",
                 "--threads", "1", "--feet", "stance", "--out", str(tmp_path / "run"), "--no-progress"]) == 0
    restyler = Restyler.load(str(tmp_path / "run" / "model.safetensors"))
    # (a pair model keeps its generator's own arm swing and hip bob; its runs take the style's elbow bend)
    bend = {"elbow_bend": restyler.amplitudes()["elbow_bend"]}
    assert restyler.feet == "stance" and feet_for(AUTO_FEET, restyler, "input") == replace(FEET["stance"], **bend)
    assert feet_for(AUTO_FEET, restyler) == replace(FEET["stance"], pace=restyler.pace(), **bend)  # --pace style
    tensors, meta = ckpt.read_checkpoint(tmp_path / "run" / "model.safetensors")
    ckpt.save_checkpoint(tmp_path / "glued.safetensors", tensors, {**meta, "feet": "glued"})
    capsys.readouterr()
    glued = str(tmp_path / "glued.safetensors")
    assert main(["restyle", str(CLIP), "-o", str(tmp_path / "x.bvh"), "--model", glued]) == 2
    err = capsys.readouterr().err
    assert "names the foot lock 'glued', which this stylecast does not know (input, stance, path)" in err
    assert err.count("\n") == 1


def test_train_refuses_an_unknown_foot_lock_before_reading_anything(tmp_path, capsys):
    code = main(["train", "--feet", "auto", "--data", str(tmp_path / "nowhere"), "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "--feet 'auto' is not a foot lock a model can name; use one of input, stance" in err
    assert err.count("\n") == 1


@needs_data
def test_restyle_keeps_the_input_skeleton_and_frame_count(tiny_run, tmp_path, capsys):
    out = tmp_path / "out.bvh"
    assert main(["restyle", str(CLIP), "-o", str(out), "--model", str(tiny_run / "model.safetensors"),
                 "--threads", "1"]) == 0
    src, res = read_bvh(CLIP), read_bvh(out)
    assert res.skeleton.names == src.skeleton.names
    assert res.num_frames == src.num_frames and res.fps == src.fps
    # The hips start where the input's do and cover ground at the exhausted pace (a normal
    # walk: 0.94 of its path); with --pace input they keep the input's own path.
    kept = tmp_path / "kept.bvh"
    assert main(["restyle", str(CLIP), "-o", str(kept), "--model", str(tiny_run / "model.safetensors"),
                 "--threads", "1", "--pace", "input"]) == 0
    hips = {name: forward_kinematics(read_bvh(path))[0][:, src.skeleton.names.index("Hips")]
            for name, path in (("input", CLIP), ("style", out), ("kept", kept))}
    travel = {name: np.linalg.norm(np.diff(h[:, [0, 2]], axis=0), axis=1).sum() for name, h in hips.items()}
    np.testing.assert_allclose(hips["style"][0, [0, 2]], hips["input"][0, [0, 2]], atol=1e-3)
    assert 0.9 < travel["style"] / travel["input"] < 0.97
    np.testing.assert_allclose(hips["kept"][:, [0, 2]], hips["input"][:, [0, 2]], atol=1e-3)
    assert main(["info", str(out)]) == 0
    capsys.readouterr()
    out60 = tmp_path / "out60.bvh"
    assert main(["restyle", str(CLIP), "-o", str(out60), "--model", str(tiny_run / "model.safetensors"),
                 "--fps", "60", "--direction", "b2a", "--intensity", "0.5", "--hop", "30"]) == 0
    assert read_bvh(out60).num_frames == 2 * src.num_frames - 1


@needs_data
def test_restyle_pads_a_clip_shorter_than_one_word(tiny_run, tmp_path):
    short = tmp_path / "short.bvh"
    write_bvh(read_bvh(CLIP).slice(0, 12), short)  # 12 frames at 30 fps = 23 at 60 fps
    out = tmp_path / "short_out.bvh"
    assert main(["restyle", str(short), "-o", str(out), "--model", str(tiny_run / "model.safetensors")]) == 0
    assert read_bvh(out).num_frames == 12


@needs_data
def test_restyle_refuses_an_unmappable_skeleton_with_a_model(tiny_run, tmp_path, capsys):
    sk = Skeleton(("root", "thing", "other"), (-1, 0, 1), np.array([[0, 0, 0], [0, 10, 0], [0, 10, 0]], float))
    clip = Clip(sk, np.tile([0.0, 0, 0, 1], (5, 3, 1)), np.zeros((5, 3)), 30.0)
    path = tmp_path / "odd.bvh"
    write_bvh(clip, path)
    code = main(["restyle", str(path), "-o", str(tmp_path / "x.bvh"), "--model", str(tiny_run / "model.safetensors")])
    err = capsys.readouterr().err
    assert code == 2 and "cannot map skeleton to the humanoid" in err and "--map" in err
    assert err.count("\n") == 1


def test_restyle_refuses_an_unknown_feet_mode_before_reading_anything(tmp_path, capsys):
    code = main(["restyle", "missing.bvh", "-o", str(tmp_path / "x.bvh"), "--feet", "glued"])
    err = capsys.readouterr().err
    assert code == 2 and "--feet 'glued' is not known; use one of auto, input, stance" in err and err.count("\n") == 1


def test_restyle_refuses_an_unknown_pace_before_reading_anything(tmp_path, capsys):
    code = main(["restyle", "missing.bvh", "-o", str(tmp_path / "x.bvh"), "--pace", "brisk"])
    err = capsys.readouterr().err
    assert code == 2 and "--pace 'brisk' is not known; use one of style, input" in err and err.count("\n") == 1


def test_restyle_refuses_a_corrupt_checkpoint(tmp_path, capsys):
    bad = tmp_path / "bad.safetensors"
    bad.write_bytes(b"not a checkpoint at all")
    code = main(["restyle", "whatever.bvh", "-o", str(tmp_path / "x.bvh"), "--model", str(bad)])
    err = capsys.readouterr().err
    assert code == 2 and "corrupt or truncated" in err and err.count("\n") == 1


@needs_data
@pytest.mark.slow
def test_eval_writes_a_report(tiny_run, tmp_path):
    model = str(tiny_run / "model.safetensors")
    assert main(["eval", "--model", model, "--variant", f"again={model}", "--out", str(tmp_path), "--max-files", "2",
                 "--threads", "1", "--judges", "2", "--recurrent-judges", "1", "--dynamics-judges", "1"]) == 0
    report = (tmp_path / "report.md").read_text()
    for section in ("The judges", "Goals, model under test, stream", "All variants, live-from-start",
                    "Per action, stream", "What the action judges took each action's 2 s windows for",
                    "What the windows were taken for", "Real motion: jerk", "Seams",
                    "The ceiling of a restyle that keeps the input's travel", "Where the Fréchet distance lies",
                    "The ceiling of a restyle that keeps the performer's timing"):
        assert section in report
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    results = metrics["results"]
    for action, row in results["input"]["stream"]["per_action"].items():  # a confusion row per action
        assert sum(row["action_taken_as"].values()) == pytest.approx(1.0)
        assert row["action_taken_as"][action] == pytest.approx(row["action_kept"])
    assert {"input", "posture", "again", "proposed"} <= set(results)
    # the input scores its own values: the instrument's zero point
    live_input = results["input"]["stream"]["overall"]
    assert live_input["jerk_ratio"]["all"] == 1.0 and live_input["slide_ratio"] == 1.0 and live_input["hold_ratio"] == 1.0
    assert "held hands and head" in report and metrics["real_target_hold_ratio"]
    assert live_input["step_height_ratio"] == 1.0
    # gait statistics: the input reads its own; each action is read against every real target take of it
    assert live_input["gait"] == live_input["gait_input"]
    ranges = metrics["real_target_gait_range"]
    assert ranges and set(ranges) <= set(results["input"]["stream"]["per_action"])
    assert all(low <= high for r in ranges.values() for low, high in r.values())
    assert "Gait statistics, stream" in report and "gait statistics inside the real target takes' range" in report
    from stylecast.models.report import summary_rows, write_summary

    worst = summary_rows({metrics["target"]: metrics})[0]["gait_outside"]  # the summary's column: the worst action
    per_action = results["proposed"]["stream"]["per_action"]
    assert worst["value"] == max(o["gait_outside"] for o in per_action.values() if "gait_outside" in o) >= 1.0
    summary = write_summary(tmp_path / "summary.md", model, {metrics["target"]: metrics}, [], 1.0).read_text()
    assert f"| {worst['value']:.2f}" in summary and "gait, worst action" in summary
    assert "step height" in report and metrics["real_target_step_ratio"]
    assert live_input["timing_sync"] == pytest.approx(1.0) and live_input["judged_target"] < 0.5
    # a one-epoch model is nearly the identity: far from the target on FMD, unlike real target windows
    assert results["proposed"]["stream"]["overall"]["fmd"] > metrics["fmd_floor"]
    # where the distance lies: the floor's parts are the floor; a mean part never exceeds the whole;
    # each action's gap is there, and the normal input's mean lies farther from the real target
    # windows than another draw of real target windows does (a different style: the known-bad case)
    real = metrics["fmd_floor_parts"]
    assert real["overall"]["fmd_judges"] == metrics["fmd_floor_judges"]
    for o in (real["overall"], live_input):
        assert all(0 <= p <= f + 1e-9 for p, f in zip(o["fmd_mean_part_judges"], o["fmd_judges"]))
        assert len(o["fmd_action_matched_judges"]) == 3
    gaps = {name: np.mean([g["feature_gap_judges"] for g in per.values()])
            for name, per in (("real", real["per_action"]), ("input", results["input"]["stream"]["per_action"]))}
    assert set(real["per_action"]) <= set(results["input"]["stream"]["per_action"])
    assert gaps["input"] > gaps["real"], gaps  # (two files a style here: real draws differ too)
    tempo = metrics["tempo_ceiling"]  # real target clips at the source's tempo, read by every judge
    assert set(tempo["per_action"]) <= set(results["input"]["stream"]["per_action"])
    assert all(r["tempo_ratio"] > 0 for r in tempo["per_action"].values())
    assert len(tempo["overall"]["judged_judges"]) == len(tempo["overall"]["fmd_judges"]) == 3
    assert "played at the normal clips' tempo lie" in report  # beside the goals it bounds
    # two conv judges of each kind, seeds 0 and 1, and a GRU judge, each with its own figures
    # and FMD space
    assert metrics["judge_panel"] == "conv 0, conv 1, gru 0" and "conv 0, conv 1, gru 0" in report
    assert metrics["judge_seeds"] == [0, 1] and len(metrics["fmd_floor_judges"]) == 3
    # the judges' thread count (--threads 1) is recorded: their figures depend on it
    assert metrics["torch_threads"] == 1 and "Trained with 1 torch thread:" in report
    proposed = results["proposed"]["stream"]["overall"]
    for key in ("judged_target", "action_kept", "action_kept_short", "fmd"):
        assert len(proposed[f"{key}_judges"]) == 3
        assert proposed[key] == pytest.approx(np.mean(proposed[f"{key}_judges"]))
    for j in metrics["judges"].values():
        assert len(j["style_accuracy_judges"]) == len(j["action_accuracy_judges"]) == 3
        assert len(j["short_action_accuracy_judges"]) == 3
        # 2 s action windows at the same hop: fewer than the one-word windows, never none
        assert 0 < j["action_windows"] <= j["windows"]
    # the action goal on 2 s windows, and the stricter one-word reading beside it
    assert "action kept, worst judge (2 s windows)" in report and "(1 s windows; stricter than the issue)" in report
    # one dynamics judge: its own style figure, a goal row and a column of the report
    assert metrics["dynamics_judge_seeds"] == [0] and len(proposed["judged_target_dynamics_judges"]) == 1
    assert all(len(j["dynamics_accuracy_judges"]) == 1 for j in metrics["judges"].values())
    assert "worst dynamics judge" in report and "judged target, dynamics" in report
    # the travel ceiling: real target clips judged by every judge, as they are and at the input's pace
    ceiling = metrics["travel_ceiling"]
    assert set(ceiling["per_action"]) == set(results["input"]["stream"]["per_action"]) - set(ceiling["actions_missing"])
    assert all(len(ceiling["overall"][k]) == 3 for k in ("as_is_judges", "source_travel_judges"))
    assert (tmp_path / "fig_hand_foot.png").exists()


def test_eval_refuses_a_malformed_variant_in_one_sentence(tmp_path, capsys):
    assert main(["eval", "--variant", "no-equals-sign", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "NAME=PATH" in err and err.count("\n") == 1


class _Identity:
    @staticmethod
    def restyle_words(words):
        return words


@needs_data
def test_restyle_path_with_an_identity_model_reproduces_the_input():
    from stylecast.models.restyle import restyle_clip

    clip = read_bvh(CLIP)
    out = restyle_clip(clip, _Identity(), hop=20)
    p_in, _ = forward_kinematics(clip)
    p_out, _ = forward_kinematics(out)
    assert out.num_frames == clip.num_frames
    assert np.abs(p_out - p_in).max() < 0.05  # centimetres


@needs_data
@pytest.mark.parametrize("kind", [[], ["--styles", "all", "--batch-size", "7", "--words-per-epoch", "14"]])
def test_train_width_and_blocks_size_the_generator_that_is_written_and_served(kind, tmp_path):
    """``--width`` / ``--blocks`` reach the network, the checkpoint records them and a
    restyler built from the file has that many channels and blocks."""
    from stylecast.models.restyler import Restyler

    run = tmp_path / "run"
    assert main(["train", "--max-words", "8", "--epochs", "1", "--batch-size", "4", "--words-per-epoch", "4", *kind,
                 "--width", "40", "--blocks", "2", "--threads", "1", "--out", str(run), "--no-progress"]) == 0
    meta = json.loads((run / "model.json").read_text())
    assert (meta["network"]["g_hidden"], meta["network"]["g_blocks"]) == (40, 2)
    # Each kind's own default dynamics term: the multistyle recipe's on, the pair's off.
    assert meta["lambdas"]["gram"] == (1.0 if kind else 0.0)
    restyler = Restyler.load(str(run / "model.safetensors"))
    generator = restyler.model if kind else restyler.model.G_a2b
    assert len(generator.blocks) == 2
    assert {p.shape[0] for name, p in generator.blocks.named_parameters() if name.endswith("c1.weight")} == {40}


@needs_data
def test_a_run_stopped_early_serves_its_last_epoch_from_the_training_checkpoint(tiny_run):
    """``checkpoint.safetensors`` (rewritten every epoch, generators and discriminators) loads
    as a model and restyles as the run's last weights (``model-raw``), not as the average."""
    from stylecast.models import data as D
    from stylecast.models.restyler import Restyler

    walk = next(f for f in D.list_files(DATA2) if f.name == CLIP.name)
    words = D.load_motion(walk).rotations[None, :60].astype(np.float64)
    last = Restyler.load(str(tiny_run / "model-raw.safetensors")).restyle_words(words)
    from_checkpoint = Restyler.load(str(tiny_run / "checkpoint.safetensors")).restyle_words(words)
    average = Restyler.load(str(tiny_run / "model.safetensors")).restyle_words(words)
    np.testing.assert_array_equal(from_checkpoint, last)
    assert np.abs(average - last).max() > 0  # the check can tell the two apart


@pytest.mark.parametrize("flags, sentence", [(["--width", "5000"], "--width 5000 is more than a live restyler can run; "
                                              "choose at most 1024"),
                                             (["--styles", "all", "--blocks", "99"], "--blocks 99 is more than")])
def test_train_refuses_a_generator_too_big_to_run_live_before_reading_anything(flags, sentence, tmp_path, capsys):
    code = main(["train", *flags, "--data", str(tmp_path / "nowhere"), "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 2 and sentence in err and err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.parametrize("options, refusal", [
    (["--model", "multistyle", "--direction", "b2a"], "model multistyle has no directions; choose its style instead"),
    (["--direction", "b2a", "--style", "exhausted"], "--direction b2a and --style exhausted both choose where the "
                                                      "restyle goes; give one of them")])
def test_restyle_refuses_a_direction_it_would_have_ignored(tmp_path, capsys, options, refusal):
    # Both once ran and wrote a file: the multistyle model to its own style, the pair
    # model to the style's end whatever the direction said.
    demo = Path(__file__).resolve().parents[1] / "daemon" / "clips" / "walk_normal.bvh.gz"
    out = tmp_path / "out.bvh"
    assert main(["restyle", str(demo), "-o", str(out), *options]) == 2
    err = capsys.readouterr().err
    assert refusal in err and "Traceback" not in err and not out.exists()


def test_restyle_takes_a_pair_models_direction(tmp_path, capsys):
    demo = Path(__file__).resolve().parents[1] / "daemon" / "clips" / "walk_normal.bvh.gz"
    for options, says in (([], "a2b: normal -> exhausted"), (["--direction", "b2a"], "b2a: exhausted -> normal")):
        assert main(["restyle", str(demo), "-o", str(tmp_path / "out.bvh"), *options]) == 0
        assert says in capsys.readouterr().out
