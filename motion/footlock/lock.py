"""Lock (``FootLock.apply``, per output frame t): the leg weight w(t) rises to 1 over
``ramp`` frames before a contact and falls over ``release`` frames after it (a dilation of
the contacts by a smoothstepped triangle each side, which looks ``ramp`` frames ahead; the
release looks only back, so it may be longer: the stance's is 8). The daemon has ``delay``
frames of input beyond the frame it renders: a lock reads no further (its ``sight``), and
where that is short of the ramp (``--latency low``: one frame) the lock sets in as the
foot comes down to the floor (``approach``), before its contact is seen. Where w > 0 the
hip-knee-ankle chain is solved analytically: the ankle goes to the input's ankle (or, with
the stance kept, beside it) and the knee bends the way the restyled knee points off its own
hip-ankle line (a knee is a hinge that folds forward of its thigh, which decides where a
straight leg's own direction is round-off; the input's knee plane, which the lock took
before, undid a restyle's turned knees: 2.7 points less judged exhausted on the panel's
mean, 0.3 less action kept); within 1 mm of full stretch the reach is eased ("soft IK"), so a knee never
snaps as its target crosses it and the ankle falls short by at most 0.37 mm there; the
foot takes the input's world rotation (turned as restyled, with the stance) and the toes
the input's local one. The result is
slerped with the restyled leg by w. Only rotations change, so bone lengths are kept by
construction. The target follows the input's ankle at every frame (not a position frozen
at touch-down), so a mistaken contact costs nothing worse than the input's own leg for
a few frames.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ..humanoid import HUMANOID_BONES
from ..skeleton import Skeleton
from .amplitude import GaitAmplitude
from .contacts import (ALL_MOVED, APPROACH_FRAMES, CONTACT_COLUMNS, FEET_COLUMNS, FLOOR_COLUMN, HISTORY_COLUMNS,
                       History, approach_columns, feet_down, frame_speeds, hysteresis, lock_kernel,
                       lock_weights, plant_or_release)
from .legs import LEGS, feet_of_one_frame, leg_chain
from .pace import Pace
from .pelvis import PelvisHeight
from .settings import ContactSettings
from .solve import LockJob, solve_lock_jobs
from .stance import StanceOffset


class FootLock:
    """Contact detection on the input stream and the lock on the output stream (see the
    package's docstring, ``motion.footlock``). ``push`` every input frame (index t = 0, 1,
    ... in order), then ``apply`` output frames up to ``sight`` frames behind the newest
    pushed input."""

    def __init__(self, skeleton: Skeleton, ramp: int | None = None, settings: ContactSettings = ContactSettings(),
                 sight: int | None = None):
        if tuple(skeleton.names) != HUMANOID_BONES:
            raise ValueError("the foot lock works on the canonical humanoid skeleton")
        self.settings = settings
        self.ramp = settings.ramp if ramp is None else max(0, int(ramp))
        # Input frames beyond an output frame the lock may read (the stream's delay); the
        # ramp's frames further ahead it foresees (``approach``).
        self.sight = self.ramp if sight is None else min(max(0, int(sight)), self.ramp)
        self.release = self.ramp if settings.release is None else max(0, int(settings.release))
        # The contacts a frame's weight reads: ``back`` frames before it (the release's, at
        # least the ramp's, which the pelvis reads: ``feet_down``) and ``ramp`` after it.
        self.back = max(self.release, self.ramp)
        self._blend = lock_kernel(self.ramp, self.release, self.back)
        self.set_offsets(skeleton.offsets)
        self.pelvis = PelvisHeight(settings.pelvis_tau, settings.pelvis_cap, settings.pelvis_flight_tau,
                                   settings.flight_memory, settings.pelvis_quick_tau, settings.pelvis_quick_share)
        self.stance = StanceOffset(settings)
        self.pace = Pace(settings)
        self.amplitude = GaitAmplitude(settings)
        self.frames = 0  # input frames pushed
        self._planted = np.zeros(2, dtype=bool)  # hysteresis state per foot
        self._floor_history: deque = deque(maxlen=settings.floor_window)  # lower ball height per frame
        self._previous = None  # (2, 2, 3): the last pushed frame's ankles and balls, each foot's [x, y, z]
        # Per input frame from _base on: the contacts (left, right), the floor height seen
        # (-inf: none known yet) and both feet's ankle and ball, columns of one history.
        self._history = History(HISTORY_COLUMNS)
        self._base = 0
        self.planted_frames = 0  # counters (tests, benchmarks)
        self.locked_frames = 0

    @classmethod
    def for_stream(cls, skeleton: Skeleton, delay: int, settings: ContactSettings = ContactSettings(),
                   fade_in: int = 0, fade_tau: float = 0.0, lead_in: int = 0, aim: float = 1.0) -> "FootLock":
        """The lock a stream with ``delay`` frames of look-ahead can run: it reads at most
        ``delay`` input frames ahead (its ``sight``), and foresees the contacts of the
        ramp's frames beyond them (the daemon and ``restyle`` both build it here).
        ``fade_in``: the frames by which the stream's first fade from pass-through to the
        restyle has ended (``words.BlendSettings.first_fade_end``), its correction low-passed
        over ``fade_tau`` frames, towards the share ``aim`` (the intensity): the stance is
        taken at that share through it. ``lead_in``: frames before the shown ones (an offline
        clip's mirrored lead-in), over which the stance follows freely (see ``StanceOffset``) and the
        gait amplitude's gains settle (``GaitAmplitude.first_frame_shown``)."""
        lock = cls(skeleton, settings=settings, sight=delay)
        lock.stance.for_fade(fade_in, fade_tau)
        lock.stance.free_until, lock.stance.aim = int(lead_in), float(aim)
        lock.amplitude.first_frame_shown = not lead_in
        return lock

    def set_offsets(self, offsets: np.ndarray) -> None:
        """The performer's proportions changed (a calibration, a VMC sender's offsets)."""
        self.offsets = np.asarray(offsets, dtype=np.float64)
        self._leg_offsets = [[tuple(self.offsets[j]) for j in leg] for leg in LEGS]
        # How far the ankle sits above the ball when the foot stands flat: the foot bone's
        # vertical extent in the T-pose (feet point forward and down).
        self.ankle_rest = float(np.mean([-self.offsets[toes][1] for _, _, _, toes in LEGS]))
        # ...and what ``approach_columns`` reads of this lock: the kernel's weight just beyond
        # its sight (none where the sight covers the ramp: nothing is foreseen)
        s, beyond = self.settings, self.back + self.sight + 1
        self._approach_numbers = np.array([[self.ankle_rest, s.plant_height, s.plant_speed, s.release_height,
                                            self._blend[beyond] if beyond < len(self._blend) else 1.0]])

    # -- input side ---------------------------------------------------------------------
    def push(self, roots: np.ndarray, rotations: np.ndarray) -> np.ndarray:
        """Input frames (n, 3) roots and (n, J, 4) local rotations, in order. Returns
        their contacts (n, 2) bool (left, right)."""
        roots = np.asarray(roots, dtype=np.float64).reshape(-1, 3)
        rotations = np.asarray(rotations, dtype=np.float64).reshape(len(roots), -1, 4)
        ankle, ball = self.feet(roots, rotations)
        if len(roots) == 1:
            contacts, lowest = _contacts_of_locks([self], ankle, ball)
        else:
            contacts, lowest = self._contacts_of_frames(ankle, ball)
        return self._record(contacts, lowest, np.stack([ankle, ball], axis=1))

    @property
    def _contacts(self) -> np.ndarray:
        return self._history.rows[:, CONTACT_COLUMNS] > 0

    @property
    def _floors(self) -> np.ndarray:
        return self._history.rows[:, FLOOR_COLUMN]

    def _record(self, contacts: np.ndarray, lowest: np.ndarray, feet: np.ndarray) -> np.ndarray:
        """Input frames' contacts (n, 2), floor heights (n,) and feet (n, ankle/ball, foot,
        xyz) into the history (the output side reads the feet there rather than run the
        input's legs again)."""
        self._planted = contacts[-1].copy()
        # A floor is known once a foot has stood on it: before a stream's first contact the
        # lowest ball seen may be a foot in the air (a stream started mid-step or with
        # made-up motion: 35 cm up, falling 3.5 cm in a frame as lower steps came, and the
        # floor step's lift popped a knee by 12 degrees in one frame), so free feet are kept
        # above nothing (-inf) until then. (Only then: no work per frame once a foot has stood.)
        if not self.planted_frames:
            lowest = np.where(np.cumsum(contacts.any(axis=1)) > 0, lowest, -np.inf)
        self._history.extend(np.column_stack([contacts, lowest, feet.reshape(len(feet), -1)]))
        before, self.frames = self.frames, self.frames + len(contacts)
        self.planted_frames += int(contacts.sum())
        if before <= 1 < self.frames:
            self._first_frame_takes(contacts[1 - before])
        return contacts

    def _first_frame_takes(self, second: np.ndarray) -> None:
        """The stream's second frame is in, with its contacts ``second`` (2,): the first frame
        takes them. It had no speed of its own (nothing came before it: ``speed[0]``), so no
        contact, and a foot standing at the start of a stream shown restyled from its first
        frame (``words.BlendSettings.start_restyled``) slid with the restyle until its lock
        ramped in: held-out clips started live slid 2.3x the input's over their first 12
        frames, 1.15x with this (1.12x after those frames). (Its floor stays unknown.)"""
        if self._base == 0:
            self._history.rows[0, CONTACT_COLUMNS] = second

    def _contacts_of_frames(self, ankle: np.ndarray, ball: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Contacts (n, 2) and floor heights (n,) of input frames, from their ankles and
        balls (n, 2, 3), the state carried on."""
        s = self.settings
        # Floor: the lowest ball height over the window, this frame included (causal).
        lowest = np.empty(len(ball))
        for i, h in enumerate(ball[:, :, 1].min(axis=1).tolist()):
            self._floor_history.append(h)
            lowest[i] = min(self._floor_history)
        # The ball rests at the floor, the ankle one foot-height above it.
        height = np.minimum(ball[:, :, 1] - lowest[:, None], ankle[:, :, 1] - lowest[:, None] - self.ankle_rest)
        prev = self._previous[:, None] if self._previous is not None else (ankle[:1], ball[:1])
        speed = np.minimum(frame_speeds(np.concatenate([prev[0], ankle])),
                           frame_speeds(np.concatenate([prev[1], ball])))
        if self._previous is None:
            speed[0] = np.inf  # a stream's first frame has no speed yet: not planted
        self._previous = np.stack([ankle[-1], ball[-1]])
        plant, release = plant_or_release(height, speed, s.plant_height, s.plant_speed, s.release_height,
                                           s.release_speed)
        return hysteresis(plant, release, self._planted), lowest

    # -- output side --------------------------------------------------------------------
    def weights(self, t0: int, n: int) -> np.ndarray:
        """Lock weights (n, 2) of output frames t0 .. t0+n-1 (needs inputs to t0+n-1+sight)."""
        return self._weights_and_down(t0, n)[0]

    def _weights_and_down(self, t0: int, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The lock weights (n, 2) and which feet are down for the pelvis (n, 2)."""
        c = self._contact_window(t0, n, np.zeros((n + self.back + self.ramp, 2)))
        windows = sliding_window_view(c, self.back + self.ramp + 1, axis=0)  # (n, 2, kernel)
        if self.sight == self.ramp:
            return lock_weights(windows, self._blend, self.back), feet_down(windows, self.ramp)
        windows = windows.copy()
        windows[..., self.back + self.sight + 1:] = 0.0  # beyond sight: not pushed yet, live
        down = feet_down(windows, self.ramp)
        newest = t0 + self.sight + np.arange(n)
        windows[..., self.back + self.sight + 1] = approach_columns(*self._approach_inputs(newest))
        return lock_weights(windows, self._blend, self.back), down

    def _approach_inputs(self, newest: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What ``approach_columns`` reads for the output frames whose newest input frames are
        ``newest`` (n,): history rows (n, frames, columns), whether each frame has a step
        before it (n, frames - 1; none where the newest is not pushed) and the lock's numbers
        (n, 5). (The frames a lock forgets are older than its ``back``, which these never
        reach: only a stream's start lies before them.)"""
        i = np.asarray(newest) - self._base
        if len(i) == 1 and APPROACH_FRAMES <= i[0] < len(self._history):  # the daemon's tick: a slice
            return (self._history.rows[None, i[0] - APPROACH_FRAMES:i[0] + 1], ALL_MOVED,
                    self._approach_numbers)
        frames = i[:, None] + np.arange(-APPROACH_FRAMES, 1)  # from the oldest
        rows = self._history.rows[np.clip(frames, 0, len(self._history) - 1)]
        moved = (frames[:, :-1] >= 0) & (i < len(self._history))[:, None]
        return rows, moved, np.repeat(self._approach_numbers, len(i), axis=0)

    def _contact_window(self, t0: int, n: int, out: np.ndarray) -> np.ndarray:
        """The contacts of frames t0 - back .. t0 + n - 1 + ramp written into ``out`` (n +
        back + ramp, 2, zeros), which is left as it is where none are known; a longer ``out``
        starts further back."""
        lo = t0 + n + self.ramp - len(out) - self._base
        a, b = max(lo, 0), min(lo + len(out), len(self._history))
        if a < b:
            out[a - lo:b - lo] = self._history.rows[a:b, CONTACT_COLUMNS]
        return out

    def _pushed(self, t0: int, n: int) -> np.ndarray:
        """The history rows of input frames t0 .. t0+n-1 (IndexError where one is not kept)."""
        rows = self._history.rows[max(t0 - self._base, 0):t0 - self._base + n]
        if t0 < self._base or len(rows) != n:
            raise IndexError("output frames the lock has no input for")
        return rows

    def apply(self, t0: int, roots: np.ndarray, inputs: np.ndarray, outputs: np.ndarray,
              mix: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Output frames t0 .. t0+n-1, in order: their input roots (n, 3), input rotations
        and restyled rotations (n, J, 4), and the share of the restyle shown in each (n,)
        (the seam blender's mix, ``words.planned_mix``; None: all of it) -> the output's
        roots (the pelvis height and the pace set) and rotations (planted feet locked).
        The inputs are the frames ``push`` was given for t0 .. t0+n-1: their feet are read
        from what was pushed, not worked out again. ``plan`` then ``solve_lock_jobs`` for
        one lock."""
        job = self.plan(t0, roots, inputs, outputs, mix)
        solve_lock_jobs([job])
        return job.new_roots, job.result

    def plan(self, t0: int, roots: np.ndarray, inputs: np.ndarray, outputs: np.ndarray,
             mix: np.ndarray | None = None) -> "LockJob":
        """Output frames t0 .. t0+n-1 (as ``apply``'s) as a job for ``solve_lock_jobs``, which
        runs the jobs of many locks together; this part needs only the contacts pushed."""
        roots = np.asarray(roots, dtype=np.float64).reshape(-1, 3)
        w, down = self._weights_and_down(t0, len(roots))
        self._forget_before(t0 - self.back)
        pushed = self._pushed(t0, len(roots))
        return LockJob(self, t0, roots, np.asarray(inputs, dtype=np.float64), np.asarray(outputs, dtype=np.float64),
                       w, down, pushed[:, FLOOR_COLUMN], mix, own=pushed[:, FEET_COLUMNS].reshape(len(roots), 2, 2, 3))

    def feet(self, roots: np.ndarray, rotations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ankle and ball positions (n, 2, 3) of both legs."""
        if len(roots) == 1:  # the daemon's case, one frame per tick: plain floats
            ankle, ball = feet_of_one_frame(roots[0], rotations[0], self._leg_offsets)
            return np.array([ankle]), np.array([ball])
        pos, _, _ = leg_chain(roots, rotations, self.offsets)
        return pos[:, :, 2], pos[:, :, 3]

    def _forget_before(self, t: int) -> None:
        drop = t - self._base
        if drop > 256:  # trim in chunks: a long stream keeps a bounded history
            self._history.drop(drop)
            self._base += drop


def push_frames(rows: list) -> None:
    """``FootLock.push`` of one input frame per row, (lock, root (3,), rotations (J, 4)),
    for many locks at once (a lock's rows in its frames' order): the daemon's tick. The
    legs' forward kinematics of every row in one vectorised ``leg_chain``, each row with
    its lock's proportions (one frame's on Python floats was 18 of a push's 30 us, per
    performer and frame), then the contacts of every lock's next frame in one pass
    (``_contacts_of_locks``; a lock with several frames this tick takes several passes)."""
    if not rows:
        return
    pos, _, _ = leg_chain(np.array([root for _, root, _ in rows], dtype=np.float64),
                          np.array([rotations for _, _, rotations in rows], dtype=np.float64),
                          np.array([lock.offsets for lock, _, _ in rows]))
    passes: list[list[int]] = []  # rows by pass: each lock's n-th frame of the tick in pass n
    frames_of: dict[int, int] = {}
    for i, (lock, _, _) in enumerate(rows):
        n = frames_of.get(id(lock), 0)
        frames_of[id(lock)] = n + 1
        if n == len(passes):
            passes.append([])
        passes[n].append(i)
    for at in passes:
        locks = [rows[i][0] for i in at]
        contacts, lowest = _contacts_of_locks(locks, pos[at, :, 2], pos[at, :, 3])
        # Each lock's record (``_record``) of its one frame: the floor unknown (-inf) until
        # a foot of the stream has stood. Written out for all locks rather than a ``_record``
        # call each: 20-30 % of push_frames at 64 locks, six of seven alternated rounds.
        known = contacts.any(axis=1) | np.array([lock.planted_frames > 0 for lock in locks])
        feet = np.stack([pos[at, :, 2], pos[at, :, 3]], axis=1).reshape(len(at), -1)
        records = np.column_stack([contacts, np.where(known, lowest, -np.inf), feet])
        for lock, row, planted, count in zip(locks, records, contacts, contacts.sum(axis=1).tolist()):
            lock._planted = planted
            lock._history.append(row)
            lock.frames += 1
            lock.planted_frames += count
            if lock.frames == 2:
                lock._first_frame_takes(planted)


def _contacts_of_locks(locks: list[FootLock], ankles: np.ndarray, balls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One input frame of each of many locks (each lock once), its ankles and balls (P, 2,
    3) -> contacts (P, 2) and floor heights (P,), each lock's state carried on as
    ``_contacts_of_frames`` carries it for one lock's frames (the same arithmetic: the
    stream-vs-clip test holds them equal). One pass for all: per lock and frame, numpy's
    per-call cost was most of the contact test's cost."""
    feet = np.stack([ankles, balls], axis=1)  # (P, ankle/ball, foot, xyz)
    previous = feet.copy()
    started = np.ones(len(locks), dtype=bool)
    planted = np.empty((len(locks), 2), dtype=bool)
    lowest = np.empty(len(locks))
    rest = np.empty(len(locks))
    thresholds = np.empty((len(locks), 4))
    for k, (lock, ball) in enumerate(zip(locks, balls[:, :, 1].min(axis=1).tolist())):
        # Floor: the lowest ball height over the lock's window, this frame included (causal).
        lock._floor_history.append(ball)
        lowest[k] = min(lock._floor_history)
        if lock._previous is None:
            started[k] = False
        else:
            previous[k] = lock._previous
        lock._previous = feet[k]
        planted[k] = lock._planted
        rest[k] = lock.ankle_rest
        s = lock.settings
        thresholds[k] = (s.plant_height, s.plant_speed, s.release_height, s.release_speed)
    # The ball rests at the floor, the ankle one foot-height above it.
    height = np.minimum(balls[:, :, 1] - lowest[:, None], ankles[:, :, 1] - lowest[:, None] - rest[:, None])
    speed = np.linalg.norm(feet - previous, axis=-1).min(axis=1)
    speed[~started] = np.inf  # a stream's first frame has no speed yet: not planted
    plant, release = plant_or_release(height, speed, *thresholds.T[:, :, None])
    return np.where(plant, True, np.where(release, False, planted)), lowest


def plan_locks(items: list) -> list["LockJob"]:
    """``FootLock.plan`` of one output frame for each of many locks, (lock, t, input root
    (3,), input rotations (J, 4), restyled rotations (J, 4), mix (1,) or None), the daemon's
    tick: the lock weights of all in one pass (per lock, the window's few numpy calls were
    most of ``plan``). Locks of different ramps plan one by one; different releases (the
    ``input`` and ``stance`` locks) share the pass, each with its own kernel."""
    if len({lock.ramp for lock, *_ in items}) > 1:
        return [lock.plan(t, root, inputs[None], outputs[None], mix) for lock, t, root, inputs, outputs, mix in items]
    ramp = items[0][0].ramp if items else 0
    back = max((lock.back for lock, *_ in items), default=ramp)
    windows = np.zeros((len(items), back + ramp + 1, 2))  # contacts t - back .. t + ramp, zero where not known
    kernels = np.zeros((len(items), back + ramp + 1))
    pushed = np.empty((len(items), HISTORY_COLUMNS))
    short = []  # (row, column beyond sight, approach inputs) of the locks that see less than their ramp
    for k, (lock, t, *_) in enumerate(items):
        lock._contact_window(t, 1, windows[k])
        if lock.sight < ramp:
            windows[k, back + lock.sight + 1:] = 0.0  # beyond sight: not pushed yet, live
            short.append((k, back + lock.sight + 1, lock._approach_inputs(np.array([t + lock.sight]))))
        kernels[k, back - lock.back:] = lock._blend
        pushed[k] = lock._pushed(t, 1)[0]
        lock._forget_before(t - lock.back)
    windows = windows.transpose(0, 2, 1)  # (locks, 2, kernel)
    down = feet_down(windows, ramp)
    if short:
        near = approach_columns(*(np.concatenate(part) for part in zip(*(inputs for _, _, inputs in short))))
        windows[[k for k, _, _ in short], :, [column for _, column, _ in short]] = near
    weights = lock_weights(windows, kernels[:, None], back)
    own = pushed[:, FEET_COLUMNS].reshape(len(items), 2, 2, 3)
    return [LockJob(lock, t, np.asarray(root, dtype=np.float64).reshape(1, 3),
                    np.asarray(inputs, dtype=np.float64)[None], np.asarray(outputs, dtype=np.float64)[None],
                    weights[k:k + 1], down[k:k + 1], pushed[k:k + 1, FLOOR_COLUMN], mix, own=own[k:k + 1])
            for k, (lock, t, root, inputs, outputs, mix) in enumerate(items)]
