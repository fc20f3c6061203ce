"""The evaluation's measures on synthetic motion with known answers: each must fail on
the known-bad case it is there to catch (a jittered copy, a sliding foot, a frozen or
re-timed motion, a different distribution), and score an identity restyle as the input."""

from __future__ import annotations

import numpy as np
import pytest

from stylecast.models import metrics as M
from stylecast.models.eval import seam_ratio, switch_mask
from stylecast.models.eval_measures import clip_measures
from stylecast.motion import rotations as rot
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default

J = len(HUMANOID_BONES)
FOOT, TOES = HUMANOID_BONES.index("LeftFoot"), HUMANOID_BONES.index("LeftToes")


def smooth_motion(frames: int = 240, seed: int = 0):
    """Slow sinusoidal local rotations and a root walking along +Z: (rotations, roots)."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 60.0
    angles = 20 * np.sin(2 * np.pi * rng.uniform(0.3, 1.2, (1, J, 3)) * t[:, None, None]
                         + rng.uniform(0, 2 * np.pi, (1, J, 3)))
    q = rot.canonical_hemisphere(rot.from_euler(angles, "ZXY"))
    roots = np.stack([np.zeros_like(t), 90 + np.zeros_like(t), 80 * t], axis=1)
    return q, roots


def jittered(q: np.ndarray, degrees: float, seed: int = 1) -> np.ndarray:
    noise = np.radians(degrees) * np.random.default_rng(seed).standard_normal((*q.shape[:-1], 3))
    return rot.multiply(q, rot.exp_map(noise))


def test_identity_restyle_scores_the_inputs_values():
    q, roots = smooth_motion()
    m = clip_measures(q, q.copy(), roots, roots.copy(), humanoid_skeleton_default())
    g_in, g_out = M.group_means(m["jerk_in"]), M.group_means(m["jerk_out"])
    assert all(g_out[g] == pytest.approx(g_in[g]) for g in g_in)
    np.testing.assert_allclose(m["slide_out"], m["slide_in"])
    assert m["sync"] == pytest.approx(1.0)


def test_a_jittered_copy_raises_jerk_the_smoothed_one_does_not():
    q, roots = smooth_motion()
    sk = humanoid_skeleton_default()
    p = M.world_positions(q, roots, sk)
    shaky = M.world_positions(jittered(q, 1.0), roots, sk)
    ratio = M.group_means(M.jerk(shaky))["all"] / M.group_means(M.jerk(p))["all"]
    assert ratio > 3.0  # one degree of frame-to-frame noise is a lot of jerk
    assert M.group_means(M.jerk(shaky))["hands"] > M.group_means(M.jerk(p))["hands"] * 3
    # the same noise summed into a slow drift (a posture change) barely moves it
    drift = rot.multiply(q, rot.exp_map(np.radians(10) * np.linspace(0, 1, len(q))[:, None, None] * np.ones(3)))
    slow = M.group_means(M.jerk(M.world_positions(drift, roots, sk)))["all"] / M.group_means(M.jerk(p))["all"]
    assert 0.8 < slow < 1.2


def test_a_one_frame_pop_fails_the_peak_jerk_though_the_mean_jerk_passes():
    """A foot turned 30 degrees for one frame of a 10 s take (the stance lock turned a
    landing foot 54 degrees in one frame) is lost in the take's mean jerk; the largest
    one-frame jerk over the input's sees it."""
    q, roots = smooth_motion(600)
    sk = humanoid_skeleton_default()
    popped = q.copy()
    popped[300, FOOT] = rot.multiply(q[300, FOOT], rot.exp_map(np.array([0.0, np.radians(30.0), 0.0])))
    m = clip_measures(q, popped, roots, roots.copy(), sk)
    assert M.group_means(m["jerk_out"])["all"] / M.group_means(m["jerk_in"])["all"] < 1.10  # the mean passes
    assert m["peak_jerk_ratio"] > 1.5  # the pop fails
    assert clip_measures(q, q.copy(), roots, roots.copy(), sk)["peak_jerk_ratio"] == pytest.approx(1.0)


def planted_foot_positions(frames: int = 120, slide_cm: float = 0.0) -> np.ndarray:
    """Positions (T, J, 3): every joint walks past at 3 cm per frame except the left foot,
    standing on the floor; with ``slide_cm`` it moves that far sideways per frame."""
    p = np.full((frames, J, 3), 100.0)
    p[:, :, 2] += 3.0 * np.arange(frames)[:, None]
    p[:, FOOT] = [10.0, 8.0, 0.0]
    p[:, TOES] = [10.0, 2.0, 10.0]
    p[:, [FOOT, TOES], 0] += slide_cm * np.arange(frames)[:, None]
    return p


def test_a_sliding_foot_raises_the_slide_a_still_one_does_not():
    still, sliding = planted_foot_positions(), planted_foot_positions(slide_cm=1.0)
    masks = M.planted(still)
    assert masks["left"].all()  # on the floor and still: planted every frame
    assert M.slide_samples(still, masks).max() == 0.0
    # the output slides 1 cm per frame where the input stood still
    assert M.slide_samples(sliding, masks).mean() == pytest.approx(1.0)
    # and the input's own sliding foot (faster than PLANT_SPEED) does not count as planted
    assert not M.planted(planted_foot_positions(slide_cm=2 * M.PLANT_SPEED))["left"].any()


def _stepping_foot(frames: int = 120, clearance_cm: float = 3.0) -> np.ndarray:
    """Positions (T, J, 3): the left foot swings forward 2 cm a frame ``clearance_cm`` above
    the floor for 20 frames, then stands 20, and again; the rest of the body far above."""
    p = np.full((frames, J, 3), 100.0)
    phase = np.arange(frames) % 40
    swing = phase < 20
    forward = 2.0 * (np.minimum(phase, 20) + 20 * (np.arange(frames) // 40))
    for joint, rest in ((FOOT, 8.0), (TOES, 2.0)):
        p[:, joint] = [10.0, rest, 0.0]
        p[:, joint, 2] = forward + (10.0 if joint == TOES else 0.0)
        p[:, joint, 1] += np.where(swing, clearance_cm * np.sin(np.pi * phase / 20.0), 0.0)
    return p


def test_a_heel_dragged_along_the_floor_raises_the_skating_though_the_planted_slide_cannot_see_it():
    lifted, dragged = _stepping_foot(clearance_cm=12.0), _stepping_foot(clearance_cm=0.0)

    def left(p):  # the left foot's ankle and ball (the fixtures' right foot floats past at one height)
        return M.skate_samples(p).reshape(4, -1)[:2]

    # Identity: the ratio is 1; standing still: nothing.
    assert left(lifted).mean() / left(lifted).mean() == 1.0
    assert left(planted_foot_positions()).max() == 0.0
    # A foot swung high is low only at lift-off and landing; dragged, it skates the whole step.
    assert left(dragged).mean() > 3 * left(lifted).mean() > 0.0
    # Planted where the input stands: the input-contact slide sees no difference at all.
    masks = M.planted(lifted)
    assert masks["left"].any()
    assert M.slide_samples(dragged, masks).mean() == M.slide_samples(lifted, masks).mean() == 0.0
    # A planted foot sliding skates too, 1 cm a frame on the floor (weight 1).
    assert left(planted_foot_positions(slide_cm=1.0)).mean() == pytest.approx(1.0)


def _swings(speed_of, steps: int = 4, stand: int = 20, swing: int = 30, stride_cm: float = 60.0) -> np.ndarray:
    """Positions (T, J, 3): the left foot stands ``stand`` frames, then swings ``stride_cm``
    forward over ``swing`` frames, ``steps`` times, with its horizontal speed through a swing
    shaped as ``speed_of(u)`` (u in (0, 1)), 10 cm up at mid-swing; the rest far above."""
    u = (np.arange(swing) + 0.5) / swing
    step = stride_cm * np.cumsum(speed_of(u)) / np.sum(speed_of(u))
    forward, height = [np.zeros(stand)], [np.zeros(stand)]
    for k in range(steps):
        forward += [k * stride_cm + step, np.full(stand, (k + 1) * stride_cm)]
        height += [10.0 * np.sin(np.pi * u), np.zeros(stand)]
    forward, height = np.concatenate(forward), np.concatenate(height)
    p = np.full((len(forward), J, 3), 100.0)
    for joint, rest, ahead in ((FOOT, 8.0, 0.0), (TOES, 2.0, 10.0)):
        p[:, joint] = np.stack([np.full_like(forward, 10.0), rest + height, forward + ahead], axis=1)
    return p


def test_a_swing_whose_ankle_stalls_or_jumps_mid_air_reads_as_dipping_and_a_real_swing_does_not():
    """A swing's ankle speed with one hump (as real walks') reads no dip; the same swings
    slumping mid-way (the pace's lag taken back as the foot lifted) or jumping forward as
    they lift and then slowing (the lock's gap crossed in its release) read a dip in every
    swing; a wobble at a swing's slow ends does not count."""
    one_hump = lambda u: np.sin(np.pi * u)  # noqa: E731
    slumped = lambda u: np.sin(np.pi * u) * (1.0 - 0.7 * np.exp(-(((u - 0.45) / 0.1) ** 2)))  # noqa: E731
    jumped = lambda u: np.sin(np.pi * u) + 2.0 * np.exp(-(((u - 0.12) / 0.05) ** 2))  # noqa: E731
    wobbly = lambda u: np.sin(np.pi * u) * (1.0 - 0.9 * np.exp(-(((u - 0.88) / 0.03) ** 2)))  # noqa: E731
    swings = M.swing_dips(_swings(one_hump))
    assert len(swings) == 4 and swings.sum() == 0  # every swing inside the take, the left foot's
    assert M.swing_dips(_swings(slumped)).tolist() == [1.0] * 4
    assert M.swing_dips(_swings(jumped)).tolist() == [1.0] * 4
    assert M.swing_dips(_swings(wobbly)).sum() == 0
    assert M.swing_dips(planted_foot_positions()).size == 0  # no swing: nothing to read


def test_dipping_swings_beyond_the_real_takes_fail_the_worst_action_goal():
    """The goal reads the share of dipping swings less the real target takes' share in the
    same action: a run dipping as often as real runs passes, walks dipping 40 % fail."""
    from stylecast.models.eval_measures import worst_actions
    from stylecast.models.report import goals_met

    overall = {"judged_target": 1.0, "action_kept": 1.0, "jerk_ratio": {"all": 1.0}, "slide_ratio": 1.0,
               "timing_sync": 1.0, "seam_ratio_relative": 1.0, "fmd_judges": [1.0]}
    per_action = {"run": {"swing_dips_excess": 0.02}, "walk": {"swing_dips_excess": 0.40}}
    overall["worst_action"] = worst_actions(per_action)
    assert overall["worst_action"]["swing_dips_excess"] == {"value": 0.40, "action": "walk"}
    assert not goals_met(overall, [1.0])["swing_dips_excess_worst_action"]
    per_action["walk"]["swing_dips_excess"] = 0.0
    overall["worst_action"] = worst_actions(per_action)
    assert goals_met(overall, [1.0])["swing_dips_excess_worst_action"]


def test_step_height_reads_how_high_a_foot_swings_and_nothing_for_a_standing_one():
    """The known-bad case it is there for: a restyle that steps higher than its input (the
    multistyle model towards elderly, whose real walks step lower). A foot swung 12 cm up
    steps about 12 cm; twice as high, twice the height; a standing foot, nothing; and the
    identity restyle scores the input's step (ratio 1)."""
    def step(p):  # the left ankle's (the fixtures' right foot floats at one height)
        return M.step_heights(p)[M.STEP_JOINTS.index("LeftFoot")]

    assert step(_stepping_foot(clearance_cm=12.0)) == pytest.approx(12.0, abs=0.2)
    assert step(_stepping_foot(clearance_cm=24.0)) == pytest.approx(2 * step(_stepping_foot(clearance_cm=12.0)))
    assert step(planted_foot_positions()) == pytest.approx(0.0, abs=1e-9)
    q, roots = smooth_motion()
    m = clip_measures(q, q.copy(), roots, roots.copy(), humanoid_skeleton_default())
    np.testing.assert_array_equal(m["step_out"], m["step_in"])


def test_timing_sync_falls_for_a_retimed_or_frozen_output():
    q, roots = smooth_motion(360)
    sk = humanoid_skeleton_default()
    p = M.world_positions(q, roots, sk)
    late = M.world_positions(np.concatenate([np.repeat(q[:1], 30, axis=0), q[:-30]]), roots, sk)  # half a second late
    assert M.timing_sync(p, p) == pytest.approx(1.0)
    assert M.timing_sync(p, late) < 0.8
    assert np.isnan(M.timing_sync(p, np.repeat(p[:1], len(p), axis=0)))  # frozen: no timing at all


def test_frechet_distance_is_zero_for_one_set_and_the_squared_shift_for_a_moved_one():
    x = np.random.default_rng(0).standard_normal((4000, 8))
    assert M.frechet_distance(x, x) == pytest.approx(0.0, abs=1e-6)
    shifted = x + np.array([3.0] + [0.0] * 7)
    assert M.frechet_distance(shifted, x) == pytest.approx(9.0, rel=1e-3)
    wider = x * 2.0  # same mean, covariance x4: tr(S + 4S - 2*2S) = tr(S) ~ 8
    assert M.frechet_distance(wider, x) == pytest.approx(8.0, rel=0.1)


def test_frechet_parts_split_a_moved_set_from_a_widened_one():
    x = np.random.default_rng(0).standard_normal((4000, 8))
    total, mean_part = M.frechet_parts(x + np.array([3.0] + [0.0] * 7), x)
    assert mean_part == pytest.approx(9.0, rel=1e-3) and total == pytest.approx(9.0, rel=1e-3)
    x -= x.mean(axis=0)
    total, mean_part = M.frechet_parts(x * 2.0, x)  # all of it the covariance's
    assert mean_part == pytest.approx(0.0, abs=1e-3) and total == pytest.approx(8.0, rel=0.1)


def test_mix_weights_give_a_set_the_reference_label_mix():
    # Two clusters (labels 0 and 1) far apart; the samples hold them 9:1, the reference 1:1.
    rng = np.random.default_rng(1)
    centres = np.array([[0.0] * 4, [6.0] + [0.0] * 3])
    labels, reference_labels = np.repeat([0, 1], [1800, 200]), np.repeat([0, 1], [1000, 1000])
    x = centres[labels] + rng.standard_normal((2000, 4))
    y = centres[reference_labels] + rng.standard_normal((2000, 4))
    w = M.mix_weights(labels, reference_labels)
    assert w[labels == 0].sum() == pytest.approx(0.5) and w[labels == 1].sum() == pytest.approx(0.5)
    assert M.frechet_distance(x, y) > 4.0  # the mix alone puts them apart...
    assert M.frechet_distance(x, y, w) < 0.1  # ...and matched, they are one distribution
    assert M.mix_weights(np.array([0, 0, 2]), np.array([1, 2]))[:2].sum() == 0.0  # 0 is not in the reference


def test_feature_gap_reads_a_moved_set_in_the_real_spread():
    rng = np.random.default_rng(2)
    y = rng.standard_normal((3000, 16)) * 0.5
    assert M.feature_gap(rng.standard_normal((3000, 16)) * 0.5, y) < 0.05  # another draw
    typical = np.sqrt(np.mean(np.sum((y - y.mean(axis=0)) ** 2, axis=1)))  # y's rms distance from its mean
    moved = y + np.eye(16)[0] * 2 * typical
    assert M.feature_gap(moved, y) == pytest.approx(2.0, rel=1e-6)
    assert M.feature_gap(y * 3.0, y) < 0.05  # a wider set in the same place: no gap (FMD's covariance part)


def test_seam_ratio_sees_a_jump_at_each_word_boundary():
    rng = np.random.default_rng(0)
    d = [np.abs(rng.normal(1.0, 0.05, (600, J)))]
    mask = [switch_mask(601, 60, live=True)]
    assert seam_ratio(d, mask) == pytest.approx(1.0, abs=0.05)
    jumped = [d[0] + 2.0 * mask[0][:, None]]
    assert seam_ratio(jumped, mask) > 2.5


@pytest.mark.parametrize("held_first", [0, 1])
def test_the_seam_mask_marks_where_a_live_stream_changes_word(held_first):
    """Each word turned by its own angle, unblended: the output jumps exactly where
    ``switch_mask`` says, also for a stream started with a held copy of its first frame
    (a half-rate source, as the evaluation's live setting replays the 30 fps files)."""
    from stylecast.models.restyle import restyle_rotations

    T, hop = 200, 4
    q = rot.from_euler(np.repeat(np.linspace(0, 20, T)[:, None, None] * [[[0.0, 1.0, 0.0]]], J, axis=1), "ZXY")

    def turn_each_word(words):  # by an angle read off the word's own last frame
        angles = 40 * rot.angle_between(words[:, -1:, :1], rot.identity((1, 1, 1)))
        return rot.multiply(rot.from_euler(angles[..., None] * np.array([1.0, 0.0, 0.0]), "ZXY"), words)

    out = restyle_rotations(q, turn_each_word, hop, live=True, decay_frames=0, correction_tau=0.0,
                            held_first=held_first).rotations
    step = rot.angle_between(out[1:], out[:-1]).max(axis=1)
    jumps = step > 3 * np.median(step)
    np.testing.assert_array_equal(jumps[60:], switch_mask(T, hop, True, held_first)[60:])
    assert not np.array_equal(jumps[60:], switch_mask(T, hop, True, 1 - held_first)[60:])


def test_floor_penetration_sees_a_foot_through_the_floor_and_not_one_above_it():
    still = planted_foot_positions()
    assert M.floor_penetration(still, still).max() == 0.0
    sunk = still.copy()
    sunk[40:50, FOOT, 1] -= 2.5  # the ankle 2.5 cm below where the input stands for 10 frames
    depth = M.floor_penetration(still, sunk)
    assert depth[40:50] == pytest.approx(2.5) and depth[:40].max() == 0.0
    lifted = still.copy()
    lifted[:, FOOT, 1] += 5.0
    assert M.floor_penetration(still, lifted).max() == 0.0


def test_a_judge_panel_with_one_fooled_judge_fails_the_style_goal():
    """The known-bad case of the judge panel: two judges call every window the target, a
    third only a quarter of them. The mean reads 75 %, the goal is read on the worst
    judge (25 %); the same holds for the action judges and, the other way up, for FMD."""
    from stylecast.models.eval_measures import summarise
    from stylecast.models.report import goal_values, goals_met

    q, roots = smooth_motion()
    clip = clip_measures(q, q.copy(), roots, roots.copy(), humanoid_skeleton_default())
    target, action = 2, 1
    style_votes = np.array([[target] * 8, [target] * 8, [target, target, 0, 0, 0, 0, 0, 0]])
    action_votes = np.array([[action] * 8, [action] * 8, [action] * 8])
    overall = summarise([clip], [style_votes], [action_votes], [action], target, ["a", "b", "c"],
                        ["x", "y", "z"])
    assert overall["judged_target_judges"] == [1.0, 1.0, 0.25]
    assert overall["judged_target"] == pytest.approx(0.75)
    assert overall["judged_as"]["c"] == pytest.approx(0.75) and overall["judged_as"]["a"] == pytest.approx(0.25)
    assert overall["action_kept"] == 1.0
    overall.update(seam_ratio_relative=1.0, fmd_judges=[2.0, 2.0, 9.0])
    values = goal_values(overall, [1.0, 1.0, 3.0])
    assert values["judged_target"] == 0.25 and values["fmd_ratio"] == pytest.approx(3.0)
    met = goals_met(overall, [1.0, 1.0, 3.0])
    assert not met["judged_target"] and not met["fmd_ratio"] and met["action_kept"]
    # With the fooled judge replaced by one that agrees, the same windows pass.
    style_votes[2] = target
    overall = summarise([clip], [style_votes], [action_votes], [action], target, ["a", "b", "c"], ["x", "y", "z"])
    overall.update(seam_ratio_relative=1.0, fmd_judges=[2.0, 2.0, 3.0])
    assert goals_met(overall, [1.0, 1.0, 3.0])["judged_target"]
    assert "judged_target_dynamics" not in goals_met(overall, [1.0, 1.0, 3.0])  # no dynamics judge ran


def test_a_posture_only_restyle_passes_the_full_judges_and_fails_the_dynamics_goal():
    """The dynamics judges' known-bad case: the full judges call every window the target
    (a posture shift reads so to them), the velocity-only judges see the input's motion
    and call half of the windows the source style, one of them all."""
    from stylecast.models.eval_measures import summarise
    from stylecast.models.report import goals_met

    q, roots = smooth_motion()
    clip = clip_measures(q, q.copy(), roots, roots.copy(), humanoid_skeleton_default())
    target, source, action = 2, 0, 1
    full = np.full((3, 8), target)
    dynamics = np.array([[target] * 4 + [source] * 4, [source] * 8])
    overall = summarise([clip], [full], [np.full((3, 8), action)], [action], target, ["a", "b", "c"],
                        ["x", "y", "z"], [dynamics])
    assert overall["judged_target"] == 1.0 and overall["judged_target_dynamics_judges"] == [0.5, 0.0]
    overall.update(seam_ratio_relative=1.0, fmd_judges=[1.0, 1.0, 1.0])
    met = goals_met(overall, [1.0, 1.0, 1.0])
    assert met["judged_target"] and not met["judged_target_dynamics"]
    # Dynamics judges that see the target's motion let it pass.
    overall = summarise([clip], [full], [np.full((3, 8), action)], [action], target, ["a", "b", "c"],
                        ["x", "y", "z"], [np.full((2, 8), target)])
    overall.update(seam_ratio_relative=1.0, fmd_judges=[1.0, 1.0, 1.0])
    assert goals_met(overall, [1.0, 1.0, 1.0])["judged_target_dynamics"]


def test_a_dynamics_judge_cannot_see_a_posture_shift_and_a_full_judge_can():
    """What makes the dynamics judge stricter: a constant pose offset (a posture-only
    restyle) leaves its probabilities unchanged, while the full judge's move."""
    from stylecast.models.classifier import WordClassifier

    rng = np.random.default_rng(0)
    windows = rng.normal(size=(16, 60, 4, 3)).cumsum(axis=1).astype(np.float32) * 0.01
    labels = np.arange(16) % 2
    shifted = windows + np.float32(0.3)
    dynamics = WordClassifier(["a", "b"], 12, seed=0, velocity_only=True).fit(windows, labels, epochs=2)
    full = WordClassifier(["a", "b"], 12, seed=0).fit(windows, labels, epochs=2)
    assert np.allclose(dynamics.probabilities(shifted), dynamics.probabilities(windows), atol=1e-4)
    assert not np.allclose(full.probabilities(shifted), full.probabilities(windows), atol=1e-3)


def _waves(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(n, 60, 4, 3) windows of joints swaying at 1 Hz (class 0) or 3 Hz (class 1), random
    phase and amplitude, and their classes."""
    rng = np.random.default_rng(seed)
    labels = np.arange(n) % 2
    t = np.arange(60) / 60.0
    freq = np.where(labels == 1, 3.0, 1.0)[:, None]
    sway = rng.uniform(0.05, 0.2, (n, 1)) * np.sin(2 * np.pi * freq * t + rng.uniform(0, 2 * np.pi, (n, 1)))
    windows = rng.normal(scale=0.005, size=(n, 60, 4, 3)) + sway[:, :, None, None]
    return windows.astype(np.float32), labels


def test_a_recurrent_judge_learns_what_a_conv_judge_learns_and_pickles():
    """The GRU judge of the panel: untrained it is at chance, trained it tells the two
    sways apart on fresh windows; its pooled features are twice its width (two directions)
    and it survives a pickle round trip (the evaluation's judges are reused that way)."""
    import pickle

    from stylecast.models.classifier import WordClassifier

    x, y = _waves(128, 0)
    fresh, truth = _waves(64, 1)
    judge = WordClassifier(["slow", "fast"], 12, seed=0, design="gru")
    assert judge.accuracy(fresh, truth) < 0.8
    judge.fit(x, y, epochs=10, batch=16)
    assert judge.accuracy(fresh, truth) >= 0.95
    assert judge.embed(fresh).shape == (64, 128)
    again = pickle.loads(pickle.dumps(judge))
    np.testing.assert_array_equal(again.probabilities(fresh), judge.probabilities(fresh))


def test_a_root_path_rescaled_to_another_pace_keeps_its_start_shape_and_heights():
    _, roots = smooth_motion()  # 80 cm/s along +Z: 1.333 cm a frame
    roots[:, 0] = 10 * np.sin(np.arange(len(roots)) / 30.0)  # with a sway, so the shape is checked too
    slower = M.with_travel_speed(roots, 0.5 * M.travel_speed(roots))
    assert M.travel_speed(slower) == pytest.approx(0.5 * M.travel_speed(roots))
    np.testing.assert_allclose(slower[0], roots[0])
    np.testing.assert_allclose(slower[:, 1], roots[:, 1])  # heights untouched
    np.testing.assert_allclose(slower[:, [0, 2]] - roots[0, [0, 2]], 0.5 * (roots[:, [0, 2]] - roots[0, [0, 2]]))
    still = np.tile(roots[:1], (50, 1))
    np.testing.assert_array_equal(M.with_travel_speed(still, 2.0), still)  # nothing to rescale


class _PaceJudge:
    """A stand-in style judge that reads travel alone: target style (1) when the hips cover
    less than 40 cm over a window, the other style (0) otherwise."""

    def style_votes(self, windows: np.ndarray) -> np.ndarray:
        travel = np.linalg.norm(windows[:, -1, 0, [0, 2]] - windows[:, 0, 0, [0, 2]], axis=-1)  # metres
        return (travel < 0.4).astype(int)[None]


def test_the_travel_ceiling_falls_for_a_style_told_by_its_pace_and_not_for_one_told_by_posture():
    """The known-bad case of a restyle that keeps the input's travel: a style whose real
    clips move slower. Judged at the source's pace, real target clips of that action no
    longer read as the target; an action whose pace is the same keeps its reading."""
    from types import SimpleNamespace

    from stylecast.models.ceilings import travel_ceiling
    from stylecast.models.judges import judge_windows

    sk = humanoid_skeleton_default()
    q, fast = smooth_motion()  # 80 cm/s: 80 cm a window
    slow = M.with_travel_speed(fast, 0.3 * M.travel_speed(fast))  # 24 cm a window: the target's pace

    def clip(action, roots):
        return SimpleNamespace(file=SimpleNamespace(action=action), rotations=q, root_positions=roots)

    source = [clip("run", fast), clip("wave", slow)]
    target = [clip("run", slow), clip("wave", slow)]
    windows = [judge_windows(c.rotations, c.root_positions, sk) for c in target]
    c = travel_ceiling(source, target, windows, 1, _PaceJudge(), sk, {"run": 3, "wave": 1, "walk": 5})
    assert c["per_action"]["run"]["as_is_judges"] == [1.0] and c["per_action"]["run"]["source_travel_judges"] == [0.0]
    assert c["per_action"]["run"]["speed_ratio"] == pytest.approx(0.3)
    assert c["per_action"]["wave"]["as_is_judges"] == [1.0] and c["per_action"]["wave"]["source_travel_judges"] == [1.0]
    # weighted by the restyled windows of each action both styles have: (3 * 0 + 1 * 1) / 4
    assert c["overall"]["as_is_judges"] == [1.0] and c["overall"]["source_travel_judges"] == [pytest.approx(0.25)]
    assert c["actions_missing"] == ["walk"]


def _waving(hz: float, seconds: float = 8.0) -> tuple[np.ndarray, np.ndarray]:
    """Every bone swinging 20 degrees about Z at ``hz``, the root still: (rotations, roots)."""
    t = np.arange(int(seconds * 60)) / 60.0
    angles = np.zeros((len(t), J, 3))
    angles[..., 0] = 20 * np.sin(2 * np.pi * hz * t)[:, None]
    return rot.canonical_hemisphere(rot.from_euler(angles, "ZXY")), np.tile([0.0, 90.0, 0.0], (len(t), 1))


def test_tempo_reads_the_beat_of_a_take_and_a_take_played_faster():
    from stylecast.models.ceilings import played_at

    sk = humanoid_skeleton_default()
    for hz in (0.75, 1.5):
        assert M.tempo(M.world_positions(*_waving(hz), sk)) == pytest.approx(hz, abs=1 / 8)  # the 8 s take's bin
    twice = played_at(*_waving(0.75), sk, 2.0)
    assert len(twice[0]) == pytest.approx(240, abs=1)  # 8 s at twice the rate: 4 s at 60 fps
    assert M.tempo(M.world_positions(*twice, sk)) == pytest.approx(1.5, abs=1 / 4)


class _TempoJudge:
    """A stand-in judge that reads the beat alone: the target style (1) when the joints move
    slower than ``threshold`` (metres a frame, against the hips); its features are that speed
    in millimetres a frame and its square, so a faster set lies away from a slower one."""

    def __init__(self, threshold: float):
        self.threshold = threshold

    @staticmethod
    def speed(windows: np.ndarray) -> np.ndarray:
        return np.abs(np.diff(windows - windows[:, :, :1], axis=1)).mean(axis=(1, 2, 3))

    def style_votes(self, windows):
        return (self.speed(windows) < self.threshold).astype(int)[None]

    dynamics_votes = style_votes

    def style_features(self, windows):
        v = 1e3 * self.speed(windows)
        return [np.stack([v, v ** 2 + 1e-3 * np.sin(np.arange(len(v)))], axis=1)]


def test_the_tempo_ceiling_falls_for_a_style_told_by_its_beat_and_not_for_one_it_shares():
    """The known-bad case of a restyle that keeps the performer's timing: a style whose real
    waves beat at half the rate. Played at the source's tempo, real target waves no longer
    read as the target and lie away from the recorded ones; an action both styles perform at
    one tempo keeps its reading and adds no distance."""
    from types import SimpleNamespace

    from stylecast.models.ceilings import played_at, tempo_ceiling
    from stylecast.models.judges import judge_windows

    sk = humanoid_skeleton_default()

    def clip(action, hz):
        q, roots = _waving(hz)
        return SimpleNamespace(file=SimpleNamespace(action=action), rotations=q, root_positions=roots)

    slow, fast = (_TempoJudge.speed(judge_windows(*_waving(hz), sk)).mean() for hz in (0.75, 1.5))
    judge = _TempoJudge(np.sqrt(slow * fast))
    actions = ["raise", "wave", "walk"]
    source, target = [clip("wave", 1.5), clip("raise", 0.75)], [clip("wave", 0.75), clip("raise", 0.75)]
    windows = [judge_windows(c.rotations, c.root_positions, sk) for c in target]
    feats = judge.style_features(np.concatenate(windows))
    labels = np.concatenate([np.full(len(w), actions.index(c.file.action)) for w, c in zip(windows, target)])
    c = tempo_ceiling(source, target, 1, judge, sk, feats, labels, actions, {"wave": 1, "raise": 3, "walk": 5})
    wave, raise_ = c["per_action"]["wave"], c["per_action"]["raise"]
    assert wave["tempo_ratio"] == pytest.approx(2.0) and raise_["tempo_ratio"] == pytest.approx(1.0)
    assert wave["judged_judges"] == [0.0] and wave["dynamics_judges"] == [0.0]
    assert raise_["judged_judges"] == [1.0] and raise_["dynamics_judges"] == [1.0]
    assert c["overall"]["judged_judges"] == [pytest.approx(0.75)]  # (1 * 0 + 3 * 1) / 4
    assert c["overall"]["fmd_judges"][0] > 1.0  # the waves' speed doubles: a gap of millimetres a frame
    # ...read at the real windows' action mix: the faster waves give half as many windows
    retimed = [judge_windows(*played_at(t.rotations, t.root_positions, sk, r), sk) for t, r in zip(target, (2.0, 1.0))]
    retimed_labels = np.concatenate([np.full(len(w), actions.index(t.file.action)) for w, t in zip(retimed, target)])
    retimed_feats = judge.style_features(np.concatenate(retimed))[0]
    matched = M.frechet_distance(retimed_feats, feats[0], M.mix_weights(retimed_labels, labels))
    assert c["overall"]["fmd_judges"][0] == pytest.approx(matched, rel=1e-6)
    assert matched != pytest.approx(M.frechet_distance(retimed_feats, feats[0]), rel=0.05)
    same = tempo_ceiling(target, target, 1, judge, sk, feats, labels, actions, {"wave": 1, "raise": 3})
    assert same["overall"]["judged_judges"] == [1.0] and same["overall"]["fmd_judges"][0] < 1e-6


def _walk(turn_degrees: float, frames: int = 240):
    """``smooth_motion`` walking at 80 cm/s along its heading; the heading holds for 1.5 s,
    turns by ``turn_degrees`` over the next second, then holds: (rotations, roots)."""
    q, _ = smooth_motion(frames)
    t = np.arange(frames)
    yaw = np.radians(turn_degrees) * np.clip((t - 90) / 60.0, 0.0, 1.0)
    q = q.copy()
    q[:, 0] = rot.multiply(rot.exp_map(np.stack([np.zeros_like(yaw), yaw, np.zeros_like(yaw)], -1)), q[:, 0])
    step = np.stack([np.sin(yaw), np.zeros_like(yaw), np.cos(yaw)], -1) * 80 / 60.0
    roots = np.concatenate([np.zeros((1, 3)), np.cumsum(step, axis=0)[:-1]]) + [0.0, 90.0, 0.0]
    return q, roots


def test_a_turning_take_starts_as_a_walk_in_one_word_and_not_in_an_action_window():
    """Why the action judges see 2 s (``judges.ACTION_WINDOW``): a turning take that walks
    straight before its turn gives a first one-word window identical to a straight walk's,
    which no judge can tell apart, while its first action window holds the turn's start."""
    from stylecast.models.judges import ACTION_WINDOW, Judges, judge_windows

    sk = humanoid_skeleton_default()
    straight, turning = _walk(0.0), _walk(90.0)
    one_word = judge_windows(*straight, sk), judge_windows(*turning, sk)
    np.testing.assert_array_equal(one_word[0][0], one_word[1][0])
    assert np.abs(one_word[0][-1] - one_word[1][-1]).max() < 1e-6  # after the turn: a straight walk again
    long = Judges.action_windows(*straight, sk), Judges.action_windows(*turning, sk)
    assert long[0].shape[1] == ACTION_WINDOW == 120
    assert np.abs(long[0][0] - long[1][0]).max() > 0.1  # metres: the turn's start is in the window


def test_a_take_shorter_than_an_action_window_is_judged_once_with_its_last_frame_held():
    from stylecast.models.judges import Judges, judge_windows

    sk = humanoid_skeleton_default()
    q, roots = smooth_motion(100)
    w = Judges.action_windows(q, roots, sk)
    assert w.shape[:2] == (1, 120)
    np.testing.assert_array_equal(w[0, 100:], np.repeat(w[0, 99:100], 20, axis=0))
    assert np.abs(np.diff(w[0, :100], axis=0)).min(axis=0).max() > 0  # the take's own frames move
    assert Judges.action_windows(q[:0], roots[:0], sk).shape[0] == 0
    assert judge_windows(q[:50], roots[:50], sk).shape[0] == 0  # one-word windows are not padded


def test_the_action_goal_is_read_on_the_2s_judges_and_the_one_word_reading_stands_beside_it():
    """The 2 s action windows and the one-word windows of a take differ in number; each is
    scored against the take's action, and a one-word panel that misses fails its own
    (stricter) row without touching the issue's."""
    from stylecast.models.eval_measures import summarise
    from stylecast.models.report import goal_values, goals_met

    q, roots = smooth_motion()
    clip = clip_measures(q, q.copy(), roots, roots.copy(), humanoid_skeleton_default())
    action = 1
    style_votes = np.full((2, 8), 2)
    long = np.full((2, 3), action)  # three 2 s windows, all kept
    short = np.array([[action] * 8, [action] * 6 + [0, 0]])  # the second judge misses a quarter
    overall = summarise([clip], [style_votes], [long], [action], 2, ["a", "b", "c"], ["x", "y", "z"],
                        windows_short_action=[short])
    assert overall["action_kept_judges"] == [1.0, 1.0]
    assert overall["action_kept_short_judges"] == [1.0, 0.75]
    overall.update(seam_ratio_relative=1.0, fmd_judges=[1.0, 1.0])
    assert goal_values(overall, [1.0, 1.0])["action_kept_short"] == 0.75
    met = goals_met(overall, [1.0, 1.0])
    assert met["action_kept"] and not met["action_kept_short"]


def _held_hand(frames: int = 240, seed: int = 0) -> np.ndarray:
    """Positions (T, J, 3) in cm: a body carried along +Z at 80 cm/s with a 0.01 cm tremor,
    its left hand held still against the hips for the first half, waving at 2 Hz after."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 60.0
    hips = np.stack([np.zeros_like(t), 90 + np.zeros_like(t), 80 * t], axis=1)
    p = hips[:, None] + rng.uniform(-50, 50, (1, J, 3)) + rng.normal(scale=0.01, size=(frames, J, 3))
    p[:, 0] = hips
    hand = HUMANOID_BONES.index("LeftHand")
    p[frames // 2:, hand, 0] += 20 * np.sin(2 * np.pi * 2 * t[frames // 2:])
    return p


def test_a_held_hand_that_drifts_fails_the_hold_measure_though_jerk_cannot_see_it():
    """The known-bad case of the holds: where the input holds its hand still, an output
    whose hand drifts slowly (3 cm at 0.5 Hz) fails the hold goal (1.5x the input's), while
    the jerk ratio stays within a percent; a copy scores 1; the waving half is not a hold."""
    p_in = _held_hand()
    masks = M.held(p_in)
    hand = HUMANOID_BONES.index("LeftHand")
    # (a waving hand pauses only at its turning points, a frame or two: no hold)
    assert masks["LeftHand"][:110].all() and not masks["LeftHand"][130:].any()
    assert M.held(p_in, min_frames=1)["LeftHand"][130:].any()
    same = M.hold_samples(p_in, masks)
    assert np.mean(M.hold_samples(p_in.copy(), masks)) / np.mean(same) == 1.0
    drifting = p_in.copy()
    drifting[:, hand, 2] += 3 * np.sin(2 * np.pi * 0.5 * np.arange(len(p_in)) / 60.0)
    ratio = np.mean(M.hold_samples(drifting, masks)) / np.mean(same)
    assert ratio > 1.5  # the report's goal, with the head and the other hand held still beside it
    jerk_ratio = M.group_means(M.jerk(drifting))["all"] / M.group_means(M.jerk(p_in))["all"]
    assert abs(jerk_ratio - 1) < 0.01


def test_a_hold_is_a_run_of_hold_frames_kept_whole_and_a_shorter_one_is_none():
    """A hand that moves 1 cm a frame but for still runs of ``HOLD_FRAMES`` frames (at the
    take's start, in its middle, at its end) and one frame shorter: the long runs are held,
    every frame of them, the short one not at all; frame by frame (``min_frames=1``) all are."""
    n = M.HOLD_FRAMES
    steps = np.ones(8 * n)  # cm a frame
    still = [range(0, n), range(3 * n, 4 * n - 1), range(5 * n, 6 * n), range(7 * n, 8 * n)]
    for run in still:
        steps[list(run)] = 0.0
    p = np.zeros((len(steps) + 1, J, 3))
    p[1:, HUMANOID_BONES.index("LeftHand"), 0] = np.cumsum(steps)
    want = np.zeros(len(steps), bool)
    for run in (still[0], still[2], still[3]):
        want[list(run)] = True
    assert np.array_equal(M.held(p)["LeftHand"], want)
    assert np.array_equal(M.held(p, min_frames=1)["LeftHand"], steps == 0)


def test_a_copy_a_frame_late_holds_as_its_input_where_a_frame_by_frame_mask_did_not():
    """The known-good case of the holds: the input itself one frame late (a restyle that changes
    nothing but its timing) holds what the input holds. Counted frame by frame, the waving
    hand's turning points (a frame or two under ``HOLD_SPEED``) were holds, and there the late
    copy's hand, still turning, moved: half again the input's (the goal is 1.5x) for nothing held less."""
    p_in = _held_hand()
    late = np.concatenate([p_in[:1], p_in[:-1]])
    for min_frames, low, high in ((M.HOLD_FRAMES, 0.9, 1.1), (1, 1.4, np.inf)):
        masks = M.held(p_in, min_frames)
        ratio = np.mean(M.hold_samples(late, masks)) / np.mean(M.hold_samples(p_in, masks))
        assert low < ratio < high, (min_frames, ratio)


def hinged_pose(frames: int = 50) -> np.ndarray:
    """Rotations of a humanoid whose elbows and knees bend as hinges do (``motion.hinges``):
    each lower arm twisted about its bone and flexed, each knee flexed, by varying angles;
    the other bones turned freely."""
    from stylecast.motion.hinges import HINGES

    q, _ = smooth_motion(frames)
    wave = np.radians(40 + 30 * np.sin(np.linspace(0, 3, frames)))
    for hinge in HINGES:
        flex = np.zeros((frames, 3))
        flex[:, hinge.flexion] = hinge.bent * wave
        twist = np.zeros((frames, 3))
        twist[:, hinge.axis] = 0.5 * wave if hinge.twists else 0.0
        q[:, HUMANOID_BONES.index(hinge.bone)] = rot.multiply(rot.exp_map(flex), rot.exp_map(twist))
    return q


def test_off_hinge_reads_a_sideways_elbow_a_twisted_knee_and_a_joint_past_straight():
    """Known-bad cases of ``off_hinge``, each read at its size in degrees; a hinge's own
    poses (flexed and a forearm twisted) read nothing."""
    from stylecast.motion.hinges import HINGES

    q = hinged_pose()
    assert M.off_hinge(q).max() < 1e-6
    by_bone = {h.bone: h for h in HINGES}
    # An elbow bent sideways: its forearm tilted 10 degrees out of the plane it flexes in.
    elbow = by_bone["LeftLowerArm"]
    j = HUMANOID_BONES.index(elbow.bone)
    pointing = rot.apply(q[:, j], np.broadcast_to(np.eye(3)[elbow.axis], (len(q), 3)))
    out_of_plane = np.cross(pointing, np.eye(3)[elbow.flexion])
    out_of_plane /= np.linalg.norm(out_of_plane, axis=1, keepdims=True)
    bad = q.copy()
    bad[:, j] = rot.multiply(rot.exp_map(np.radians(10.0) * out_of_plane), q[:, j])
    np.testing.assert_allclose(M.off_hinge(bad), 10.0, atol=1e-6)
    for bone, axis, degrees in (("RightLowerLeg", 1, 6.0),  # a knee twisted
                                ("LeftLowerLeg", 2, 8.0)):  # ... and bent sideways
        bad = q.copy()
        j = HUMANOID_BONES.index(bone)
        v = np.zeros(3)
        v[axis] = np.radians(degrees)
        bad[:, j] = rot.multiply(bad[:, j], rot.exp_map(np.broadcast_to(v, (len(q), 3))))
        np.testing.assert_allclose(M.off_hinge(bad), degrees, atol=1e-6, err_msg=bone)
    straight = q.copy()
    for bone in ("RightLowerArm", "RightLowerLeg"):  # straight, then 5 degrees past it
        hinge = by_bone[bone]
        v = np.zeros(3)
        v[hinge.flexion] = -hinge.bent * np.radians(5.0)
        straight[:, HUMANOID_BONES.index(bone)] = rot.exp_map(np.broadcast_to(v, (len(q), 3)))
        np.testing.assert_allclose(M.off_hinge(straight), 5.0, atol=1e-6, err_msg=bone)
        straight[:, HUMANOID_BONES.index(bone)] = q[:, HUMANOID_BONES.index(bone)]


def test_the_hinge_goal_is_read_beyond_the_input_s_own(tmp_path):
    from stylecast.models.eval_measures import summarise
    from stylecast.models.report import goal_values, goals_met

    q, roots = smooth_motion()
    q = hinged_pose(len(q))
    bent = jittered(q, 3.0)  # every bone a few degrees off, the hinges too
    clips = [clip_measures(q, out, roots, roots.copy(), humanoid_skeleton_default()) for out in (q.copy(), bent)]
    for clip, met in zip(clips, (True, False)):
        overall = summarise([clip], [np.zeros((1, 4), int)], [np.zeros((1, 4), int)], [0], 0, ["a"], ["x"])
        overall.update(seam_ratio_relative=1.0, fmd_judges=[1.0])
        assert (goal_values(overall, [1.0])["off_hinge_excess"] <= 1.0) == met
        assert goals_met(overall, [1.0])["off_hinge_excess"] == met


def test_a_slide_confined_to_a_few_actions_fails_the_worst_action_goal():
    """The known-bad case the overall ratio hid: planted feet sliding 2.5x the input's in
    the standing actions only, the overall slide under the bar. Read on the worst action it
    fails, and names the action; a restyle that slides nowhere passes."""
    from stylecast.models.eval_measures import summarise, worst_actions
    from stylecast.models.report import goal_values, goals_met

    q, roots = smooth_motion()
    clip = clip_measures(q, q.copy(), roots, roots.copy(), humanoid_skeleton_default())
    target, action = 2, 1
    overall = summarise([clip], [np.full((3, 8), target)], [np.full((3, 8), action)], [action], target,
                        ["a", "b", "c"], ["x", "y", "z"])
    overall.update(seam_ratio_relative=1.0, fmd_judges=[1.0, 1.0, 1.0], slide_ratio=1.3)
    per_action = {"walk": {"slide_ratio": 1.1, "skate_ratio": 1.2}, "wave": {"slide_ratio": 2.5, "skate_ratio": 1.0},
                  "raise": {"slide_ratio": float("nan"), "skate_ratio": 1.4}}  # (no planted frame: no figure)
    overall["worst_action"] = worst_actions(per_action)
    assert overall["worst_action"] == {"slide_ratio": {"value": 2.5, "action": "wave"},
                                       "skate_ratio": {"value": 1.4, "action": "raise"}}
    met = goals_met(overall, [1.0, 1.0, 1.0])
    assert met["slide_ratio"] and not met["slide_ratio_worst_action"] and met["skate_ratio_worst_action"]
    per_action["wave"]["slide_ratio"] = 1.0
    overall["worst_action"] = worst_actions(per_action)
    assert goal_values(overall, [1.0, 1.0, 1.0])["slide_ratio_worst_action"] == 1.1
    assert goals_met(overall, [1.0, 1.0, 1.0])["slide_ratio_worst_action"]
    del overall["worst_action"]  # a report written before the reading: no such goal, no failure
    assert "slide_ratio_worst_action" not in goals_met(overall, [1.0, 1.0, 1.0])


def walking_gait(frames: int = 240, twist_deg: float = 6.0, width_cm: float = 12.0, swing_cm: float = 15.0,
                 facing_deg: float = 30.0, across_cm: float = 0.0):
    """A synthetic take with known gait statistics: the hips' facing swings ``twist_deg``
    about ``facing_deg`` once a second, the ankles stand ``width_cm`` apart across that facing
    and the hands swing ``swing_cm`` forward and back, in counter-phase, and ``across_cm``
    across the body, together, once a second ->
    (rotations (T, J, 4), positions (T, J, 3)). Sinusoids over whole cycles: a standard
    deviation of amplitude / sqrt 2."""
    t = np.arange(frames) / 60.0
    phase = 2 * np.pi * t
    yaw = np.radians(facing_deg + twist_deg * np.sin(phase))
    q = np.tile(np.array([0.0, 0.0, 0.0, 1.0]), (frames, J, 1))
    q[:, 0] = np.stack([np.zeros_like(yaw), np.sin(yaw / 2), np.zeros_like(yaw), np.cos(yaw / 2)], axis=-1)
    across = np.stack([np.cos(yaw), np.zeros_like(yaw), -np.sin(yaw)], axis=-1)
    forward = np.stack([np.sin(yaw), np.zeros_like(yaw), np.cos(yaw)], axis=-1)
    hips = np.stack([np.zeros_like(t), 90 + np.zeros_like(t), 80 * t], axis=-1)
    p = np.repeat(hips[:, None], J, axis=1)
    for name, side in (("LeftFoot", 1), ("RightFoot", -1)):
        p[:, HUMANOID_BONES.index(name)] = hips + side * width_cm / 2 * across - [0, 85, 0]
    for name, side in (("LeftHand", 1), ("RightHand", -1)):
        p[:, HUMANOID_BONES.index(name)] = (hips + side * 20 * across
                                            + side * swing_cm * np.sin(phase)[:, None] * forward
                                            + across_cm * np.sin(phase)[:, None] * across)
    return q, p


def test_gait_statistics_read_a_known_gait_and_a_twisted_or_crossed_copy():
    """Each statistic reads its known value at any facing; the known-bad cases the
    evaluation missed read as such: hips swung twice as far, feet crossed."""
    for facing in (0.0, 30.0, 170.0):
        g = M.gait_statistics(*walking_gait(facing_deg=facing))
        assert g["hips_twist_deg"] == pytest.approx(6.0 / np.sqrt(2), rel=0.02)
        assert g["stance_width_cm"] == pytest.approx(12.0, rel=1e-6)
        assert g["arm_swing_cm"] == pytest.approx(15.0 / np.sqrt(2), rel=0.02)
    twisted = M.gait_statistics(*walking_gait(twist_deg=12.0))
    assert twisted["hips_twist_deg"] == pytest.approx(2 * 6.0 / np.sqrt(2), rel=0.02)
    assert M.gait_statistics(*walking_gait(width_cm=-3.0))["stance_width_cm"] == pytest.approx(-3.0, rel=1e-6)
    # a slow turn of the whole take is not a twist: the running mean takes it
    q, p = walking_gait(twist_deg=0.0)
    yaw = np.radians(np.linspace(0, 90, len(q)))
    q[:, 0] = np.stack([np.zeros_like(yaw), np.sin(yaw / 2), np.zeros_like(yaw), np.cos(yaw / 2)], axis=-1)
    assert M.hips_twist(M.hips_yaw(q), p) < 0.05


def waving_hand(sway_cm: float, raised_cm: float = 20.0, facing_deg: float = 30.0, frames: int = 240):
    """A standing take (``walking_gait`` without twist or swing) whose left hand is held
    ``raised_cm`` over its elbow from the first to the last quarter of the take, swaying
    ``sway_cm`` across the body at 3 Hz (a wave; whole cycles in the 1 s running mean)
    while it is up -> (rotations, positions)."""
    q, p = walking_gait(frames=frames, twist_deg=0.0, swing_cm=0.0, facing_deg=facing_deg)
    p[:, :, 2] -= p[:, :1, 2]  # standing
    yaw = np.radians(facing_deg)
    across = np.array([np.cos(yaw), 0.0, -np.sin(yaw)])
    up = np.zeros(frames, bool)
    up[frames // 4: frames - frames // 4] = True
    sway = np.where(up, sway_cm * np.sin(2 * np.pi * 3.0 * np.arange(frames) / 60.0), 0.0)
    elbow, hand = HUMANOID_BONES.index("LeftLowerArm"), HUMANOID_BONES.index("LeftHand")
    p[:, elbow] = p[:, 0] + 20 * across + [0.0, 40.0, 0.0]
    p[:, hand] = p[:, elbow] + np.where(up, raised_cm, -raised_cm)[:, None] * [0.0, 1.0, 0.0] + sway[:, None] * across
    return q, p


def test_arm_swing_across_reads_hands_swung_across_and_not_a_raised_wave():
    """Hands swung 6 cm across the body as they walk read 6 / sqrt 2 at any facing, beside
    the forward swing, which stays as it was; a walk without it reads 0; a wave of a raised
    hand is the raised hand's sway, not this (the hanging frames' running mean sees a little
    of it), and a hand that never hangs for a second is not read."""
    for facing in (0.0, 30.0, 170.0):
        g = M.gait_statistics(*walking_gait(facing_deg=facing, across_cm=6.0))
        assert g["arm_swing_across_cm"] == pytest.approx(6.0 / np.sqrt(2), rel=0.02)
        assert g["arm_swing_cm"] == pytest.approx(15.0 / np.sqrt(2), rel=0.02)
    assert M.gait_statistics(*walking_gait())["arm_swing_across_cm"] == pytest.approx(0.0, abs=1e-9)
    waving = M.gait_statistics(*waving_hand(8.0))
    assert waving["arm_swing_across_cm"] < 0.1 * waving["raised_hand_sway_cm"]
    q, p = walking_gait(across_cm=6.0)
    for hand, elbow in (("LeftHand", "LeftLowerArm"), ("RightHand", "RightLowerArm")):
        p[:, HUMANOID_BONES.index(elbow)] = p[:, HUMANOID_BONES.index(hand)] - [0.0, 2 * M.RAISED_HAND_CM, 0.0]
    assert M.arm_swing_across(M.hips_yaw(q), p) == 0.0


def test_raised_hand_sway_reads_a_wave_and_not_a_still_raise_or_a_lowered_hand():
    """A hand waved 8 cm across the body while raised sways 8 / sqrt 2 at any facing; held
    still it sways nothing (a raise); the same sway with the hand below its elbow is no
    raised hand's; a walk's hands are never raised."""
    for facing in (0.0, 30.0, 170.0):
        assert M.gait_statistics(*waving_hand(8.0, facing_deg=facing))["raised_hand_sway_cm"] == \
            pytest.approx(8.0 / np.sqrt(2), rel=0.03)
    assert M.gait_statistics(*waving_hand(0.0))["raised_hand_sway_cm"] == pytest.approx(0.0, abs=1e-9)
    assert M.gait_statistics(*waving_hand(8.0, raised_cm=-5.0))["raised_hand_sway_cm"] == 0.0
    assert M.gait_statistics(*walking_gait())["raised_hand_sway_cm"] == 0.0
    # a damped wave reads outside a range of real waves, and is named
    from stylecast.models.eval_measures import gait_outside

    damped = M.gait_statistics(*waving_hand(4.0))
    factor, name = gait_outside(damped, {"raised_hand_sway_cm": (6.5, 8.0)})
    assert name == "raised_hand_sway_cm" and factor == pytest.approx(5.5 / (4.0 / np.sqrt(2)), rel=0.03)


def bent_arms(bend_deg: float, facing_deg: float = 30.0, frames: int = 120):
    """``walking_gait`` with arms: each upper arm hangs 30 cm from its shoulder joint and the
    forearm (25 cm) is bent ``bend_deg`` forward of it."""
    q, p = walking_gait(frames=frames, facing_deg=facing_deg)
    yaw = np.radians(facing_deg)
    forward = np.array([np.sin(yaw), 0.0, np.cos(yaw)])
    bend = np.radians(bend_deg)
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        shoulder = p[:, 0] + [0.0, 45.0, 0.0] + sign * 18.0 * np.array([np.cos(yaw), 0.0, -np.sin(yaw)])
        elbow = shoulder - [0.0, 30.0, 0.0]
        p[:, HUMANOID_BONES.index(f"{side}UpperArm")] = shoulder
        p[:, HUMANOID_BONES.index(f"{side}LowerArm")] = elbow
        p[:, HUMANOID_BONES.index(f"{side}Hand")] = elbow + 25.0 * (np.cos(bend) * np.array([0.0, -1.0, 0.0])
                                                                    + np.sin(bend) * forward)
    return q, p


def test_elbow_bend_reads_a_known_bend_and_a_straightened_run_reads_outside():
    """Arms bent 55 degrees read 55 at any facing, straight ones 0, folded ones 120; arms
    without length (a synthetic take without arms) read NaN, which no range fails. Runs
    restyled towards feminine bent them 38 degrees on average where every real feminine run
    bends them 49-61: outside, and named."""
    from stylecast.models.eval_measures import gait_outside

    for facing in (0.0, 30.0, 170.0):
        assert M.elbow_bend(None, bent_arms(55.0, facing)[1]) == pytest.approx(55.0, abs=1e-6)
    assert M.elbow_bend(None, bent_arms(0.0)[1]) == pytest.approx(0.0, abs=1e-4)
    assert M.elbow_bend(None, bent_arms(120.0)[1]) == pytest.approx(120.0, abs=1e-6)
    assert np.isnan(M.gait_statistics(*walking_gait())["elbow_bend_deg"])
    assert gait_outside({"elbow_bend_deg": float("nan")}, {"elbow_bend_deg": (49.0, 61.0)}) == (1.0, "")
    straightened = M.gait_statistics(*bent_arms(38.0))
    factor, name = gait_outside(straightened, {"elbow_bend_deg": (49.0, 61.0)})
    assert name == "elbow_bend_deg" and factor == pytest.approx((49.0 - 5.0) / 38.0, rel=1e-6)
    assert gait_outside(M.gait_statistics(*bent_arms(46.0)), {"elbow_bend_deg": (49.0, 61.0)}) == (1.0, "")


def test_arm_forward_reads_how_far_forward_the_hands_are_carried_at_any_facing():
    """Arms hanging straight read 0 degrees at any facing; the forearms bent 90 degrees
    forward carry the hands atan2(25, 30) forward of the shoulder (40 degrees), bent back
    as far, the same behind: the measure of ``gait_amplitude.ARM_FORWARDS``, where the
    multistyle model's walks towards active held the hands 5.7 degrees forward against real
    active walks' 19-31."""
    for facing in (0.0, 30.0, 170.0):
        assert M.arm_forward(np.radians(facing), bent_arms(0.0, facing)[1]) == pytest.approx(0.0, abs=1e-9)
        forward = M.arm_forward(np.radians(facing), bent_arms(90.0, facing)[1])
        assert forward == pytest.approx(np.degrees(np.arctan2(25.0, 30.0)), abs=1e-6)
        assert M.arm_forward(np.radians(facing), bent_arms(-90.0, facing)[1]) == pytest.approx(-forward, abs=1e-6)


def test_gait_outside_the_real_range_fails_the_goal_and_names_the_statistic():
    """Inside every real take's range (widened by the tolerance, 1 degree or cm) reads 1;
    hips swung 1.5x past the most any real take swings, or feet crossed or 4 cm apart
    against a range of 8-14 cm, fail the worst-action gait goal and are named. The input
    reads its own statistics (the zero point)."""
    from stylecast.models.eval_measures import gait_outside, summarise, worst_actions
    from stylecast.models.report import goals_met

    q, p = walking_gait()
    ranges = {"hips_twist_deg": (3.0, 6.0), "stance_width_cm": (8.0, 14.0), "arm_swing_cm": (8.0, 12.0)}
    inside = M.gait_statistics(q, p)
    assert gait_outside(inside, ranges) == (1.0, "")
    assert gait_outside(M.gait_statistics(*walking_gait(width_cm=7.5)), ranges) == (1.0, "")  # within tolerance
    twisted = M.gait_statistics(*walking_gait(twist_deg=(6.0 + 1.0) * 1.5 * np.sqrt(2)))
    factor, name = gait_outside(twisted, ranges)
    assert name == "hips_twist_deg" and factor == pytest.approx(1.5, rel=0.03)
    crossed = M.gait_statistics(*walking_gait(width_cm=-1.0))
    assert gait_outside(crossed, ranges) == (100.0, "stance_width_cm")
    factor, name = gait_outside(M.gait_statistics(*walking_gait(width_cm=3.5)), ranges)
    assert name == "stance_width_cm" and factor == pytest.approx(2.0)

    qs, roots = smooth_motion()
    clip = clip_measures(qs, qs.copy(), roots, roots.copy(), humanoid_skeleton_default())
    assert clip["gait_in"] == clip["gait_out"]
    overall = summarise([clip], [np.full((3, 8), 0)], [np.full((3, 8), 0)], [0], 0, ["a"], ["x"])
    assert overall["gait"] == overall["gait_input"]
    overall.update(seam_ratio_relative=1.0, fmd_judges=[1.0, 1.0, 1.0])
    per_action = {"walk": {}, "wave": {}}
    for a, stats in (("walk", twisted), ("wave", inside)):
        per_action[a]["gait_outside"], per_action[a]["gait_outside_of"] = gait_outside(stats, ranges)
    overall["worst_action"] = worst_actions(per_action)
    assert overall["worst_action"]["gait_outside"]["action"] == "walk"
    assert overall["worst_action"]["gait_outside"]["of"] == "hips_twist_deg"
    assert not goals_met(overall, [1.0, 1.0, 1.0])["gait_outside_worst_action"]
    per_action["walk"]["gait_outside"], per_action["walk"]["gait_outside_of"] = gait_outside(inside, ranges)
    overall["worst_action"] = worst_actions(per_action)
    assert goals_met(overall, [1.0, 1.0, 1.0])["gait_outside_worst_action"]


def test_gait_statistics_tell_real_styles_apart_on_real_walks(bandai_root):
    """On real Bandai walks: every held-out feminine walk lies inside the range of the
    training feminine walks on all three statistics, and the held-out normal walks, a
    different style, fall outside it: they twist their hips more than any feminine walk, by
    more than the tolerance."""
    from stylecast.models.data import files_for_style, list_files, load_motion, bandai_skeleton
    from stylecast.models.eval_measures import gait_outside

    files = list_files(bandai_root / "dataset-2" / "data")
    skeleton = bandai_skeleton(files)

    def stats(style: str, split: str) -> list[dict]:
        out = []
        for f in files_for_style(files, style, split):
            if f.action == "walk":
                m = load_motion(f)
                out.append(M.gait_statistics(m.rotations, M.world_positions(m.rotations, m.root_positions, skeleton)))
        return out

    train = stats("feminine", "train")
    ranges = {k: (min(s[k] for s in train), max(s[k] for s in train)) for k in M.GAIT_STATISTICS}
    for s in stats("feminine", "val"):
        assert gait_outside(s, ranges)[0] < 1.1, s
    for s in stats("normal", "val"):
        factor, name = gait_outside(s, ranges)
        assert factor > 1.0 and name == "hips_twist_deg", (s, ranges)
        assert s["stance_width_cm"] > ranges["stance_width_cm"][1]  # wider too, within the tolerance


def test_held_out_takes_a_frame_late_pass_every_judge_free_goal(bandai_root):
    """The instrument's known-good case on real motion: every held-out normal Bandai take a frame
    late (frames 1 on against frames 0 on), a restyle that changes nothing but its timing, reads
    as the input on every judge-free measure (jerk 1.001, largest one-frame jerk 1.02, slide 1.05,
    skating and step height 1.00, holds 1.02) but the timing sync, there to see it (0.95).
    Counted frame by frame (``min_frames=1``, the holds until 2026-12-08) the swinging hands' and
    the bobbing head's turns were holds, and the same copy held 1.10x the input's, its runs 2.19x."""
    from stylecast.models.data import bandai_skeleton, files_for_style, list_files, load_motion
    from stylecast.models.eval_measures import clip_measures, summarise

    files = list_files(bandai_root / "dataset-2" / "data")
    skeleton = bandai_skeleton(files)
    takes = [load_motion(f) for f in files_for_style(files, "normal", "val")]
    clips = [clip_measures(m.rotations[1:], m.rotations[:-1], m.root_positions[1:], m.root_positions[:-1], skeleton)
             for m in takes]
    late = summarise(clips, [], [], [0] * len(clips), 0, ["normal"], ["any"])
    assert late["jerk_ratio"]["all"] < 1.01 and late["peak_jerk_ratio"] < 1.1
    assert late["slide_ratio"] < 1.1 and late["skate_ratio"] < 1.02 and abs(late["step_height_ratio"] - 1) < 0.01
    assert late["hold_ratio"] < 1.05
    assert 0.9 < late["timing_sync"] < 0.99

    def hold_ratios_frame_by_frame() -> tuple[float, float]:
        """The late copies' holds over the input's counted frame by frame: every take, the runs."""
        ratios = []
        for chosen in (takes, [m for m in takes if m.file.action == "run"]):
            own, moved = [], []
            for m in chosen:
                p = M.world_positions(m.rotations, m.root_positions, skeleton)
                masks = M.held(p[1:], min_frames=1)
                own.append(M.hold_samples(p[1:], masks))
                moved.append(M.hold_samples(p[:-1], masks))
            ratios.append(np.concatenate(moved).mean() / np.concatenate(own).mean())
        return ratios[0], ratios[1]

    every, runs = hold_ratios_frame_by_frame()
    assert every > 1.08 and runs > 2.0, (every, runs)


def real_statistic(bandai_root, read, action: str, *styles: str) -> list[list[float]]:
    """``read`` (the hips' facing, positions -> a figure) of every real Bandai take of
    ``action``, training and held out, one list per style of ``styles``."""
    from stylecast.models.data import bandai_skeleton, files_for_style, list_files, load_motion

    files = list_files(bandai_root / "dataset-2" / "data")
    skeleton = bandai_skeleton(files)
    out = []
    for style in styles:
        motions = [load_motion(f) for split in ("train", "val") for f in files_for_style(files, style, split)
                   if f.action == action]
        out.append([read(M.hips_yaw(m.rotations), M.world_positions(m.rotations, m.root_positions, skeleton))
                    for m in motions])
    return out


def test_arm_swing_across_tells_real_styles_apart_on_real_walks(bandai_root):
    """On real Bandai walks, training and held out: every elderly walk swings its hands across
    the body less than any active walk (0.6-1.3 against 7.1-10.7 cm in the training split)."""
    elderly, active = real_statistic(bandai_root, M.arm_swing_across, "walk", "elderly", "active")
    assert max(elderly) < min(active), (elderly, active)


def test_raised_hand_sway_tells_real_styles_apart_on_real_waves(bandai_root):
    """On real Bandai waves of one hand: every feminine take, training or held out, sways
    less than any normal take (feminine waves barely sway: the hand held at the shoulder),
    and youthful waves sway more than normal ones on average."""
    feminine, normal, youthful = real_statistic(bandai_root, M.raised_hand_sway, "wave-left-hand",
                                                "feminine", "normal", "youthful")
    assert max(feminine) < min(normal), (feminine, normal)
    assert np.mean(youthful) > 1.2 * np.mean(normal), (youthful, normal)


def test_real_walks_of_every_style_keep_one_hump_per_swing(bandai_root):
    """The held-out walks and turning walks of all seven styles: no swing's ankle speed dips
    (0 of 777), which is what the swing-dip goal reads a walk's restyle against."""
    from stylecast.models.data import bandai_skeleton, files_for_style, list_files, load_motion
    from stylecast.models.styles import STYLES

    files = list_files(bandai_root / "dataset-2" / "data")
    skeleton = bandai_skeleton(files)
    swings = [M.swing_dips(M.world_positions(m.rotations, m.root_positions, skeleton))
              for m in (load_motion(f) for s in STYLES for f in files_for_style(files, s, "val")
                        if f.action.startswith("walk"))]
    swings = np.concatenate(swings)
    assert len(swings) > 700 and swings.sum() == 0
