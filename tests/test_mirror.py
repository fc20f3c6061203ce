"""The left-right mirror image of humanoid motion (motion/mirror.py) and the training words
it adds (models/data.py ``with_mirror``, ``train --mirror``)."""

from __future__ import annotations

import numpy as np

from stylecast.models import data as D
from stylecast.models.metrics import world_positions
from stylecast.models.representation import word_heading
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default
from stylecast.motion.mirror import MIRROR_BONES, mirror_positions, mirror_rotations, reflect_rotations


def _random_motion(frames: int = 40, seed: int = 0) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    q = Rotation.random(frames * len(HUMANOID_BONES), random_state=seed).as_quat()
    return q.reshape(frames, len(HUMANOID_BONES), 4)


def test_twins_are_the_same_bone_on_the_other_side():
    named = {HUMANOID_BONES[j]: HUMANOID_BONES[t] for j, t in enumerate(MIRROR_BONES)}
    assert named["LeftHand"] == "RightHand" and named["RightToes"] == "LeftToes"
    assert named["Hips"] == "Hips" and named["Head"] == "Head"
    assert np.array_equal(MIRROR_BONES[MIRROR_BONES], np.arange(len(HUMANOID_BONES)))


def test_mirror_image_is_the_reflected_pose_with_sides_swapped():
    """FK of the mirrored rotations on a symmetric skeleton = the original joints with x
    negated and every joint swapped with its twin. Swapping alone, or reflecting alone,
    is a different pose."""
    skeleton = humanoid_skeleton_default()
    local = _random_motion()
    roots = np.random.default_rng(1).normal(size=(len(local), 3)) * 30
    expected = mirror_positions(world_positions(local, roots, skeleton))[:, MIRROR_BONES]
    got = world_positions(mirror_rotations(local), mirror_positions(roots), skeleton)
    assert np.abs(got - expected).max() < 1e-9
    for wrong in (local[:, MIRROR_BONES], reflect_rotations(local)):
        assert np.abs(world_positions(wrong, mirror_positions(roots), skeleton) - expected).max() > 10.0
    assert np.allclose(mirror_rotations(mirror_rotations(local)), local)


def test_mirror_actions_swap_sides_and_stay_in_the_dataset():
    actions = ["raise-up-both-hands", "raise-up-left-hand", "raise-up-right-hand", "run", "walk",
               "walk-turn-left", "walk-turn-right", "wave-both-hands", "wave-left-hand", "wave-right-hand"]
    assert D.mirror_action("walk-turn-left") == "walk-turn-right"
    assert D.mirror_action("wave-right-hand") == "wave-left-hand"
    assert D.mirror_action("walk") == "walk" and D.mirror_action("raise-up-both-hands") == "raise-up-both-hands"
    assert sorted(D.mirror_action(a) for a in actions) == actions


def test_mirrored_real_left_turn_turns_right_and_keeps_its_takes_apart(bandai_root, tmp_path):
    """A real walk-turn-left, mirrored: the hips turn the other way by the same angle, and the
    words are labelled walk-turn-right; the next word of a mirrored word is never a recorded
    one."""
    data = bandai_root / "dataset-2" / "data"
    recorded = D.load_wordset("normal", "train", data, tmp_path, hop=20, max_words=200)
    both = D.load_wordset("normal", "train", data, tmp_path, hop=20, max_words=200, mirror=True)
    n = len(recorded)
    assert len(both) == 2 * n and np.array_equal(both.words[:n], recorded.words)
    assert np.array_equal(both.words[n:], mirror_rotations(recorded.words))

    labels = D.actions_present(D.list_files(data))
    from stylecast.models.content import action_labels

    a_rec, a_both = action_labels(recorded, labels), action_labels(both, labels)
    assert np.array_equal(a_both[:n], a_rec)
    assert [labels[a] for a in a_both[n:]] == [D.mirror_action(labels[a]) for a in a_rec]
    assert all(f.mirrored for f in both.files[len(recorded.files):])

    nxt = D.next_words(both)
    assert np.all((nxt[:n] < n)) and np.all((nxt[n:] == -1) | (nxt[n:] >= n))

    left = next(f for f in D.files_for_style(D.list_files(data), "normal") if f.action == "walk-turn-left")
    motion = D.load_motion(left, tmp_path)
    turn = np.unwrap(word_heading(D.cut_words(motion.rotations, hop=10)))
    turn_mirrored = np.unwrap(word_heading(D.cut_words(mirror_rotations(motion.rotations), hop=10)))
    assert turn[-1] - turn[0] > np.radians(45)  # the recorded take turns left (about +Y)
    assert np.allclose(turn_mirrored - turn_mirrored[0], -(turn - turn[0]), atol=1e-5)
