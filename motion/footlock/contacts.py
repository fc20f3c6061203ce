"""Contacts (``FootLock.push``, per input frame, in arrival order): a foot is planted when
its ankle or its ball is near the floor and nearly still, with hysteresis (a higher bar
to let go than to plant) so a noisy foot does not flicker. The floor is the lowest the
ball of the foot has been over the last ``floor_window`` frames (live sources do not say
where their floor is).

Here: the contact test's events and states (``plant_or_release``, ``hysteresis``; the lock
runs them on one lock's frames or on one frame of many locks), each lock's history of what
was pushed (``History``), and the lock weights a frame's contact window gives
(``lock_kernel``, ``lock_weights``, and ``approach`` for a lock that sees less far ahead
than its ramp)."""

from __future__ import annotations

import numpy as np

from ..smoothing import smoothstep

# A foot's coming down to a contact (``approach``), for a lock that sees fewer frames ahead
# than its ramp: cm a frame from which a foot is not coming down (before the contact test
# plants it at 0.6, a walk's foot slows through 1.2-2.0 over its last six frames, a run's
# from 6-8 to under 3 in its last two; a swing moves 3-6), the most its lock weight moves a
# frame, and the frames read before the newest. Chosen on the training split (``approach``):
# 2.5, 3.5 and 6 cm/frame, 0.1-0.3 a frame over 4-10 frames were screened.
APPROACH_SPEED = 4.5
APPROACH_SLEW = 0.2
APPROACH_FRAMES = 5

ALL_MOVED = np.ones((1, APPROACH_FRAMES), dtype=bool)  # ``FootLock._approach_inputs``' common case

# The columns of a lock's per-frame history (``FootLock._history``): the contacts (left,
# right), the floor height and the feet, (ankle, ball) x (left, right) x xyz.
CONTACT_COLUMNS, FLOOR_COLUMN, FEET_COLUMNS = slice(0, 2), 2, slice(3, 15)
HISTORY_COLUMNS = 15


class History:
    """Rows of numbers appended at the end and dropped from the front, in one preallocated
    array: appending a frame by concatenation copied the whole history every frame, per
    performer."""

    def __init__(self, columns: int, capacity: int = 512):
        self._rows = np.zeros((capacity, columns))
        self._count = 0

    def __len__(self) -> int:
        return self._count

    @property
    def rows(self) -> np.ndarray:
        return self._rows[:self._count]

    def _room(self, n: int) -> None:
        if self._count + n > len(self._rows):
            grown = np.zeros((max(2 * len(self._rows), self._count + n), self._rows.shape[1]))
            grown[:self._count] = self.rows
            self._rows = grown

    def append(self, row: np.ndarray) -> None:
        self._room(1)
        self._rows[self._count] = row
        self._count += 1

    def extend(self, rows: np.ndarray) -> None:
        self._room(len(rows))
        self._rows[self._count:self._count + len(rows)] = rows
        self._count += len(rows)

    def drop(self, n: int) -> None:
        """Forget the first ``n`` rows."""
        kept = self._rows[n:self._count].copy()
        self._rows[:len(kept)] = kept
        self._count = len(kept)


def lock_kernel(ramp: int, release: int, back: int) -> np.ndarray:
    """The lock weight a contact gives the frames around it, over ``back`` frames before one
    (zero beyond ``release``) and ``ramp`` after it, from past to future: a smoothstep of a
    triangle each side, so the lock sets in and lets go with zero slope. A linear ramp's
    corners at touch-down were the largest jerk of a restyled walk (its largest one-frame
    jerk 1.33x the input's, median over held-out walks; 1.01x smoothstepped; runs 1.88x ->
    1.51x, planted-foot slide 1.32 -> 1.16)."""
    linear = np.zeros(back + ramp + 1)
    linear[back - release:back] = 1.0 - np.arange(release, 0, -1) / (release + 1)  # a contact that has ended
    linear[back:] = 1.0 - np.arange(ramp + 1) / (ramp + 1)  # a contact to come
    return smoothstep(linear)


def lock_weights(windows: np.ndarray, kernel: np.ndarray, back: int) -> np.ndarray:
    """Contact windows (..., back + ramp + 1) and their kernel (``lock_kernel``) -> the lock
    weights: the nearest contact before a frame lets go, the nearest one from it on sets in,
    and the two are joined as 1 - (1 - letting go)(1 - setting in), which is smooth where
    the two overlap (a swing shorter than release + ramp frames). Their larger one has a
    corner there: a foot set down 7 frames into a clip, its lock over the mirrored lead-in
    let go over 8 frames, popped the toes at 6.7 cm/frame^3 (the input's largest: 2.4)."""
    before = (windows[..., :back] * kernel[..., :back]).max(axis=-1, initial=0.0)
    after = (windows[..., back:] * kernel[..., back:]).max(axis=-1)
    return 1.0 - (1.0 - before) * (1.0 - after)


def approach_columns(rows: np.ndarray, moved: np.ndarray, numbers: np.ndarray) -> np.ndarray:
    """``FootLock._approach_inputs`` of one or many locks (m rows) -> the contact windows'
    value (m, 2) for the frame just beyond each lock's sight: ``approach`` as the weight the
    lock kernel there gives it."""
    ankle_rest, plant_height, plant_speed, release_height = (n[:, None, None] for n in numbers[:, :4].T)
    near = approach(rows, moved, ankle_rest, plant_height, plant_speed, release_height)
    column = numbers[:, 4:]
    return np.minimum(near, column) / column


def approach(rows: np.ndarray, moved: np.ndarray, ankle_rest, plant_height, plant_speed,
             release_height) -> np.ndarray:
    """A lock's history rows of APPROACH_FRAMES + 1 consecutive input frames (m, frames,
    columns) -> how far each foot of the last has come down to a contact (m, 2), in [0, 1]:
    per frame, 1 where the foot is as low and slow as the contact test plants it, 0 from
    ``release_height`` up or ``APPROACH_SPEED`` on, smoothstepped between, and 0 where no
    floor is known yet; then slew-limited to ``APPROACH_SLEW`` a frame over the frames read,
    from a stream's first step on (``moved`` (m, frames - 1): the frame has a step before
    it; nothing was shown before a stream started, so a foot coming down in its first
    frames is not held back).

    Why: a lock sets in over ``ramp`` frames before a contact, and a stream with less delay
    than that (``--latency low``: one frame) saw the contact too late and snapped the lock
    in over a frame. A foot coming down slows on its way, so the lock sets in as it does
    (``FootLock.sight``). Measured on the training split's normal clips with the pair
    default at hop 1 (a scratch screen; the held-out figures are in the model card): jerk
    1.19x the input's -> 1.08x, planted-foot slide 1.59x -> 1.10x, the worst clip's largest
    one-frame jerk 3.6x -> 2.6x (the real contacts four frames ahead: 1.03x, 1.10x, 2.1x).
    Unlimited, a walk's speed, stepped as a 30 Hz capture's is, switched the lock in by 0.65
    in one frame (6.0x the input's largest one-frame jerk); limited from the frames after a
    floor became known alone, a live walk's first frames popped a foot at 7.3x; and a foot
    lifting slowly off the floor let go at once. A wrong guess costs little: the lock's
    target is the input's own foot."""
    feet = rows[:, :, FEET_COLUMNS].reshape(*rows.shape[:2], 2, 2, 3)  # (m, frame, ankle/ball, foot, xyz)
    floor = rows[:, 1:, FLOOR_COLUMN][..., None]
    height = np.minimum(feet[:, 1:, 1, :, 1] - floor, feet[:, 1:, 0, :, 1] - floor - ankle_rest)  # (m, frame, foot)
    speed = np.linalg.norm(np.diff(feet, axis=1), axis=-1).min(axis=2)  # (m, frame, foot)
    slow = np.clip((APPROACH_SPEED - speed) / (APPROACH_SPEED - plant_speed), 0.0, 1.0)
    low = np.clip((release_height - height) / (release_height - plant_height), 0.0, 1.0)
    near = np.where(moved[..., None], smoothstep(slow) * smoothstep(low), np.nan)  # (m, frame, foot)
    # Slew-limited over the frames read, from the first with a step (NaN: none yet)
    slewed = near[:, 0]
    for frame in near.transpose(1, 0, 2)[1:]:
        slewed = np.where(np.isnan(slewed), frame,
                          np.clip(frame, slewed - APPROACH_SLEW, slewed + APPROACH_SLEW))
    return np.nan_to_num(slewed, nan=0.0)




def feet_down(windows: np.ndarray, ramp: int) -> np.ndarray:
    """Contact windows (..., back + ramp + 1) -> whether a contact lies within ``ramp``
    frames either side: the feet the pelvis stands on (``PelvisHeight``). A foot that a
    longer release still holds is lifting, and its gap is no stance: counted, it dropped the
    hips and popped a knee (the pair default's worst held-out clip: 1.2 -> 2.6x the input's
    largest one-frame jerk with an 8-frame release)."""
    return windows[..., windows.shape[-1] - 2 * ramp - 1:].max(axis=-1) > 0


def plant_or_release(height, speed, plant_height, plant_speed, release_height, release_speed):
    """The contact test's events per frame and foot: a foot low and still plants, one high
    or fast lets go (``ContactSettings``; thresholds scalars or one per row)."""
    return (height < plant_height) & (speed < plant_speed), (height > release_height) | (speed > release_speed)


def frame_speeds(positions: np.ndarray) -> np.ndarray:
    """(n+1, 2, 3) consecutive positions -> (n, 2) distance moved per frame."""
    return np.linalg.norm(np.diff(positions, axis=0), axis=-1)


def hysteresis(plant: np.ndarray, release: np.ndarray, start: np.ndarray) -> np.ndarray:
    """State per frame and foot: on at ``plant``, off at ``release``, else as before,
    vectorised: each frame takes the most recent event at or before it."""
    n = len(plant)
    event = np.where(plant, 1, np.where(release, -1, 0))  # the two tests never hold together
    idx = np.where(event != 0, np.arange(n)[:, None], -1)
    last = np.maximum.accumulate(idx, axis=0)
    taken = np.take_along_axis(event, np.maximum(last, 0), axis=0)
    return np.where(last >= 0, taken > 0, start[None, :])
