import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from stylecast.motion import Clip
from stylecast.motion import rotations as rot
from stylecast.motion.resample import resample
from tests.rigs import bandai_like_skeleton


def random_clip(seed: int, frames: int = 40, fps: float = 30.0) -> Clip:
    sk = bandai_like_skeleton()
    rng = np.random.default_rng(seed)
    angles = np.cumsum(rng.normal(0, 4, (frames, len(sk), 3)), axis=0)  # smooth-ish motion
    return Clip(sk, rot.from_euler(angles, "ZXY"), np.cumsum(rng.normal(0, 1, (frames, 3)), axis=0), fps)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 10_000), st.integers(2, 50))
def test_30_to_60_to_30_returns_the_original_frames(seed, frames):
    clip = random_clip(seed, frames)
    up = resample(clip, 60.0)
    assert up.num_frames == 2 * frames - 1
    back = resample(up, 30.0)
    assert back.num_frames == frames
    assert rot.angle_between(back.rotations, clip.rotations).max() < 1e-3
    assert np.abs(back.root_positions - clip.root_positions).max() < 1e-9


def test_midpoints_are_slerp_and_lerp():
    clip = random_clip(7, 5)
    up = resample(clip, 60.0)
    mid = rot.slerp(clip.rotations[1], clip.rotations[2], 0.5)
    assert rot.angle_between(up.rotations[3], mid).max() < 1e-9
    assert np.allclose(up.root_positions[3], clip.root_positions[1:3].mean(axis=0))


def test_any_rate_keeps_duration():
    clip = random_clip(3, 31)  # 1 s at 30 fps
    for fps in (24.0, 59.94, 120.0):
        out = resample(clip, fps)
        assert (out.num_frames - 1) / fps == pytest.approx(1.0, abs=1.0 / fps)
