"""The judge panel kept on disk (``models/judge_cache.py``): a panel read back must be the
panel training would give, to the bit, and any change to what it was trained on must train
it anew."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import torch

from stylecast.models.judges import Judges
from stylecast.motion.humanoid import humanoid_skeleton_default

from tests.test_metrics import jittered, smooth_motion

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _motions(jitter: float = 0.0):
    """Two styles by two actions of synthetic takes (one of them jittered by ``jitter``
    degrees: the known change of training data)."""
    out = []
    for k, (style, action) in enumerate([("a", "x"), ("a", "y"), ("b", "x"), ("b", "y")]):
        q, roots = smooth_motion(150, seed=k)
        if k == 3 and jitter:
            q = jittered(q, jitter)
        out.append(SimpleNamespace(rotations=q, root_positions=roots, file=SimpleNamespace(style=style, action=action)))
    return out


def _fit(cache, motions=None, fresh=False):
    lines = []
    torch.manual_seed(123)
    judges = Judges(["a", "b"], ["x", "y"], seed=5, panel=1, dynamics=1, recurrent=1).fit(
        motions or _motions(), humanoid_skeleton_default(), lines.append, cache_dir=cache, fresh=fresh)
    return judges, lines[-1], torch.get_rng_state()


def _readings(judges, windows):
    return np.concatenate([j.probabilities(windows) for j in
                           judges.style_panel + judges.action_panel + judges.short_action_panel + judges.dynamics_panel],
                          axis=1)


def test_a_panel_read_from_the_cache_reads_every_window_as_the_trained_one_and_leaves_the_same_generator(tmp_path):
    from stylecast.models.judges import judge_windows

    windows = judge_windows(*smooth_motion(200, seed=9), humanoid_skeleton_default())
    trained, said, rng_trained = _fit(tmp_path)
    assert " trained, on " in said and len(list((tmp_path / "judges").glob("panel-*.safetensors"))) == 1
    read, said, rng_read = _fit(tmp_path)
    assert " read from " in said and "--fresh-judges" in said
    np.testing.assert_array_equal(_readings(read, windows), _readings(trained, windows))
    assert torch.equal(rng_read, rng_trained)  # what runs after the judges draws the same numbers
    # Without the cache, the same: the panel is the one training gives.
    uncached, said, _ = _fit(None)
    assert " trained, on " in said
    np.testing.assert_array_equal(_readings(uncached, windows), _readings(trained, windows))


def test_other_training_windows_a_broken_file_or_fresh_judges_train_anew(tmp_path):
    from stylecast.models.judges import judge_windows

    windows = judge_windows(*smooth_motion(200, seed=9), humanoid_skeleton_default())
    first, _, _ = _fit(tmp_path)
    # One take jittered by a degree: another key, so the stored panel is not read.
    other, said, _ = _fit(tmp_path, _motions(jitter=1.0))
    assert " trained, on " in said and len(list((tmp_path / "judges").glob("panel-*.safetensors"))) == 2
    assert not np.array_equal(_readings(other, windows), _readings(first, windows))  # the check can fail
    # A file cut short is trained over, with no traceback.
    for path in (tmp_path / "judges").glob("panel-*.safetensors"):
        path.write_bytes(path.read_bytes()[:100])
    again, said, _ = _fit(tmp_path)
    assert " trained, on " in said
    np.testing.assert_array_equal(_readings(again, windows), _readings(first, windows))
    assert " read from " in _fit(tmp_path)[1]  # ... and stored again
    assert " trained, on " in _fit(tmp_path, fresh=True)[1]
