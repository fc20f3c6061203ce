"""Resampling a clip to another frame rate: slerp for rotations, linear for positions.

Frame i of the result sits at time i / fps. The result spans the same duration as the
input, so 30 -> 60 -> 30 fps returns the original frames (slerp at a key is the key).
"""

from __future__ import annotations

import numpy as np

from . import rotations as rot
from .clip import Clip


def resample(clip: Clip, fps: float) -> Clip:
    if not fps > 0:
        raise ValueError(f"frame rate must be positive, got {fps}")
    if abs(fps - clip.fps) < 1e-9 or clip.num_frames < 2:
        return clip.replace(fps=float(fps))
    span = (clip.num_frames - 1) / clip.fps
    count = int(np.floor(span * fps + 1e-6)) + 1
    src_time = np.arange(count) * (clip.fps / fps)  # in source frames
    lo = np.minimum(np.floor(src_time + 1e-9).astype(int), clip.num_frames - 1)
    hi = np.minimum(lo + 1, clip.num_frames - 1)
    frac = np.clip(src_time - lo, 0.0, 1.0)
    J = len(clip.skeleton)
    rotations = rot.slerp(clip.rotations[lo], clip.rotations[hi], np.repeat(frac[:, None], J, axis=1))
    lerp = lambda a: a[lo] + (a[hi] - a[lo]) * frac.reshape(-1, *([1] * (a.ndim - 1)))  # noqa: E731
    translations = None if clip.translations is None else lerp(clip.translations)
    return Clip(clip.skeleton, rot.canonical_hemisphere(rotations), lerp(clip.root_positions), float(fps), translations)
