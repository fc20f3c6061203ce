"""Motion words and seam blending: the one streaming algorithm shared by the live daemon
and offline ``stylecast restyle`` (so the two produce the same frames).

The walk of a frame, frame indices counted from the start of a performer's stream:

* ``WordCutter`` keeps a ring buffer of input rotations and, every ``hop`` frames, emits
  a motion word: the last ``WORD_LENGTH`` (60) frames. Word ends lie on the grid
  e = 59 + phase + k hop (phase 0 unless the daemon staggers performers), from the first
  such frame at or after the stream's start (``first_word_end``): before its first frame
  a stream is taken to have held that frame, as a performer standing in the first pose
  would, so the first words are that pose held and then the motion so far, and the first
  frame is shown restyled: waiting for a whole word of real frames left the first 1.4 s
  unrestyled, most of a short take, and a fade-in from the first frame the first 0.5 s
  (models/checkpoints/MODEL_CARD.md, "A stream's start").
* The restyler turns each word into a restyled word (elsewhere, possibly late).
* ``SeamBlender`` renders output frame t at time t + delay (delay >= hop frames). Frame t
  is served by the first word whose end e >= t (so e <= t + hop - 1). The first frame a
  word serves, e + 1 - hop, is rendered at e + 1 + (delay - hop): the model has
  delay - hop + 1 frame periods per word, and a word not there by then is late.

The seam (the paper's section 4.5: consecutive words disagree where they meet) is
removed by an *offset blend*: when serving switches from word A to word B, the blender
computes the rotation that carries B onto what was just shown,
offset = shown(t-1) * B(t-1)^-1 (B overlaps A, so B(t-1) exists), applies it on top of B
and lets a critically damped spring (time constant ``decay_frames``) pull it back to
identity, keeping its rate of change across switches. The output is continuous in pose
and in velocity at every switch and settles onto B's own motion; unlike a crossfade of
overlapping windows this needs no extra latency, so delay = hop is enough. At hop 1 the
switch comes every frame and the spring acts as a smoothing filter on the words.

A source that ends is held: its last frame is pushed again each frame until a word has
covered its final frame, so the last frames are restyled like the others (offline, the
end of a clip is padded the same way).

Pass-through and restyled output are mixed by ``mix`` in [0, 1]: it moves towards the
requested intensity (0 in bypass, when no word is available yet or when a word is late)
by at most 1 / crossfade_frames per frame, so stopping, late results, bypass and
intensity changes all fade instead of popping. A stream's first frame has nothing before
it to pop from: it is shown restyled when its word is there (``start_restyled``; the
held-out takes are 2-9 s long, and a half-second fade-in was a good part of one). While
no word is available the restyled pose is approximated by carrying the last restyle
residual (restyled * input^-1) onto the live input, so the fade-out has something
continuous to fade from.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from . import rotations as rot
from .hinges import keep_hinges
from .smoothing import CORRECTION_TAU, CorrectionFilter

WORD_LENGTH = 60
DEFAULT_HOP = 4  # frames between words when nobody says otherwise: serve's default latency preset, restyle, eval


def first_word_end(hop: int, word_length: int = WORD_LENGTH, phase: int = 0) -> int:
    """The frame at which a stream's first word ends: the earliest frame of the grid
    ``word_length - 1 + phase + k hop`` (k may be negative) that is not before the stream's
    first frame. That word serves frame 0 on (it ends within a hop of it)."""
    return (word_length - 1 + phase) % hop


def half_rate_shift(hop: int, word_length: int = WORD_LENGTH, phase: int = 0) -> int | None:
    """Held copies of its first frame (0 or 1) that put every word end of a half-rate
    stream on a source frame; None where none can (an odd hop: word ends alternate).

    A source at half the output rate (a 30 fps replay) brings its resampled frames in
    pairs, an interpolated frame and then the source frame on the grid, both when the
    source frame arrives: the frames counted from the stream's first, the source frames
    are the even ones. A word that ends on an interpolated frame is cut a period after its
    own time, so the stream has to be shown a period later than ``delay`` for that word to
    keep its slack. Where every word ends on a source frame, none is, and the stream can
    be shown ``delay`` periods after each frame's own time like a 60 Hz one: the daemon
    (``Session``) and ``restyle --live`` both start such a stream with its first frame held
    once more when the grid's ends would be odd."""
    if hop % 2:
        return None
    return first_word_end(hop, word_length, phase) % 2


def serving_word_end(t, hop: int, word_length: int = WORD_LENGTH, phase: int = 0):
    """End frame of the word that serves frame t >= 0 (the first grid end >= t); t may be an
    int or an integer array. Plain arithmetic: the daemon asks once per performer a tick."""
    first = first_word_end(hop, word_length, phase)
    return first - ((first - t) // hop) * hop


def cut_words(frames: np.ndarray, hop: int, word_length: int = WORD_LENGTH,
              phase: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Every word a ``WordCutter`` fed ``frames`` (T, J, 4) one by one would emit, in one
    gather: (ends (N,), words (N, word_length, J, 4)), each word in one hemisphere over
    time. Offline restyling cuts whole clips this way (the per-frame loop cost more than
    the rest of the stream code together). Frames before the first are the first held."""
    frames = np.asarray(frames, dtype=np.float64)
    ends = np.arange(first_word_end(hop, word_length, phase), len(frames), hop)
    index = np.maximum(ends[:, None] + np.arange(1 - word_length, 1)[None, :], 0)
    return ends, rot.canonical_hemisphere(frames[index], axis=1)


@dataclass
class WordCutter:
    """Ring buffer of input rotations; emits a word every ``hop`` frames, the first when
    frame ``first_word_end`` arrives (the buffer starts full of the first frame)."""

    hop: int
    word_length: int = WORD_LENGTH
    phase: int = 0
    frames_seen: int = 0
    # Words in one hemisphere over time (``canonical_hemisphere``). False: as the frames
    # came, for a consumer that makes many words continuous in one pass (the daemon's
    # model thread, a tick's batch at once: per word in the output loop it was 5 % of the
    # loop at 64 performers).
    continuous: bool = True
    # Each frame is written twice, at i and i + word_length, so the last word_length frames
    # are always one contiguous slice: a word is one copy, where stacking 60 frames kept
    # in a deque cost about as much as the rest of the cut (the daemon cuts per performer).
    _ring: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if not 1 <= self.hop <= self.word_length:
            raise ValueError(f"hop must be between 1 and {self.word_length} frames, got {self.hop}")

    def push(self, rotations: np.ndarray) -> tuple[int, np.ndarray] | None:
        """Add one frame (J, 4); return (end frame, word (60, J, 4)) when a word completes."""
        frame = np.asarray(rotations, dtype=np.float64)
        n = self.word_length
        if self._ring is None:  # before the stream's first frame: that frame, held
            self._ring = np.broadcast_to(frame, (2 * n, *frame.shape)).copy()
        t = self.frames_seen
        self._ring[t % n] = self._ring[t % n + n] = frame
        self.frames_seen += 1
        first = first_word_end(self.hop, n, self.phase)
        if t >= first and (t - first) % self.hop == 0:
            start = (t + 1) % n  # where frame t - n + 1, the word's first, sits
            word = self._ring[start:start + n]
            return t, rot.canonical_hemisphere(word) if self.continuous else word.copy()
        return None


@dataclass
class BlendSettings:
    hop: int
    delay: int | None = None  # frames between a frame's arrival and its output; >= hop
    decay_frames: float | None = None  # time constant of the seam offset; 0 disables blending
    crossfade_frames: int = 30  # pass-through <-> restyled fades
    # A stream's first frame is shown restyled when its word is there (the correction's
    # low-pass starts settled on it, the pace on the first step: nothing was shown before
    # it to fade from); False: it fades in from pass-through over ``crossfade_frames``.
    start_restyled: bool = True
    correction_tau: float = CORRECTION_TAU  # low-pass of the correction after blending; 0 = off
    word_length: int = WORD_LENGTH
    # Shifts the word grid by this many frames (0 <= phase < hop). The daemon staggers
    # groups of performers so their words do not all reach the model on the same tick.
    phase: int = 0

    def __post_init__(self) -> None:
        if not 1 <= self.hop <= self.word_length:
            raise ValueError(f"hop must be between 1 and {self.word_length} frames, got {self.hop}")
        if self.delay is None:
            self.delay = self.hop
        if self.delay < self.hop:
            raise ValueError(f"delay ({self.delay} frames) must be at least the hop ({self.hop} frames)")
        if not 0 <= self.phase < self.hop:
            raise ValueError(f"phase must be between 0 and hop - 1 frames, got {self.phase}")
        if self.decay_frames is None:
            self.decay_frames = float(min(max(self.hop, 4), 15))
        self.crossfade_frames = max(1, int(self.crossfade_frames))

    @property
    def first_fade_end(self) -> int:
        """The stream frame by which its first fade from pass-through to the restyle has
        ended: none when it starts restyled; else the first word serves frame 0, so the
        crossfade's length, and the correction's low-pass after it (a triple pole: within
        1.4 % of a step 8 tau on)."""
        if self.start_restyled:
            return 0
        return self.crossfade_frames + int(np.ceil(8 * self.correction_tau))


def start_of(restyler) -> bool:
    """``BlendSettings.start_restyled`` for a stream restyled by ``restyler``: the model's own
    ``start_restyled`` where it names one, else True."""
    return bool(getattr(restyler, "start_restyled", True))


def correction_tau_of(restyler) -> float:
    """``BlendSettings.correction_tau`` for a stream restyled by ``restyler``: the model's own
    ``correction_tau`` where it names one, else ``CORRECTION_TAU``."""
    return float(getattr(restyler, "correction_tau", CORRECTION_TAU))


def stream_settings_of(restyler) -> dict:
    """The ``BlendSettings`` a model names for the streams it restyles (``start_of``,
    ``correction_tau_of``), by their field names: ``serve``, ``restyle`` and ``eval`` all
    take them from here, so none of them can miss one."""
    return {"start_restyled": start_of(restyler), "correction_tau": correction_tau_of(restyler)}


def _spring_at(offset: np.ndarray, c2: np.ndarray, omega, k) -> np.ndarray:
    """A critically damped spring pulling ``offset`` to zero, k frames on, in closed form:
    x(k) = (x0 + c2 k) e^(-w k) with c2 = v0 + w x0."""
    return (offset + c2 * k) * np.exp(-omega * k)


def _spring(offset: np.ndarray, velocity: np.ndarray, omega: float, k: int):
    """The spring's offset and rate of change (J, 3) k frames on (the end of a run)."""
    c2 = velocity + omega * offset
    k = np.float64(k)
    fade = np.exp(-omega * k)
    return (offset + c2 * k) * fade, (velocity - omega * c2 * k) * fade


def _pose(factors: tuple) -> np.ndarray:
    """A pose kept as two factors: ("offset", rotation vector, pose) or ("rotation",
    quaternion, pose) -> their product."""
    kind, left, right = factors
    return rot.multiply(rot.exp_map(left) if kind == "offset" else left, right)


def _poses(factors: list[tuple]) -> np.ndarray:
    """``_pose`` of many (n, J, 4), each kind's left factors turned into quaternions in one pass."""
    left = np.empty((len(factors), *factors[0][2].shape))
    for kind, convert in (("offset", rot.exp_map), ("rotation", np.asarray)):
        at = [i for i, f in enumerate(factors) if f[0] == kind]
        if at:
            left[at] = convert(np.stack([factors[i][1] for i in at]))
    return rot.multiply(left, np.stack([f[2] for f in factors]))


def _is_input(mix) -> bool:
    """A run shown as pass-through needs no restyled poses."""
    return np.isscalar(mix) and mix == 0.0


class SeamBlender:
    """Assembles output frames from restyled words (see the module docstring).

    ``render_block`` renders consecutive frames at once: within a run of frames served by
    one word, the seam offset is a geodesic power (slerp from identity to the offset,
    s = decay ** n) and the mix a clipped ramp, both closed-form, so a run costs a few
    vectorised operations instead of a Python step per frame. ``restyle`` renders whole
    clips, the daemon one frame of every performer per tick (``plan_block`` per blender,
    then one ``render_planned`` for all), through the same code.
    """

    def __init__(self, settings: BlendSettings, num_bones: int, phase: int | None = None):
        # ``settings`` may be shared by many blenders (the daemon's live settings); the
        # word-grid phase is this stream's own, so it can be given apart from them.
        self.settings = settings
        self.phase = settings.phase if phase is None else phase
        self.num_bones = num_bones
        self._words: dict[int, np.ndarray] = {}  # word end -> restyled word
        self._serving: int | None = None  # end frame of the word currently served
        # The seam offset as a rotation vector (J, 3) and its change per frame, at the
        # previous frame; a critically damped spring pulls it to zero.
        self._offset = np.zeros((num_bones, 3))
        self._offset_velocity = np.zeros((num_bones, 3))
        # The restyled pose shown for the previous frame, and the last pose from a word
        # (with ``_last_input``, its input: their ratio is carried on), each kept as the
        # two factors of a product (``_pose``) and multiplied out only when needed, at a
        # switch of word or when the words stop: not every frame.
        self._shown: tuple | None = None
        self._residual = rot.identity((num_bones,))  # restyled * input^-1 while no word
        self._last_restyled: tuple | None = None
        self._last_input: np.ndarray | None = None
        self._omega = 0.0 if not settings.decay_frames else 1.0 / float(settings.decay_frames)
        self.mix = 0.0
        self._first_frame = True  # nothing shown yet (``BlendSettings.start_restyled``)
        self.late_frames = 0

    def add_word(self, end: int, restyled: np.ndarray, continuous: bool = False) -> None:
        """``continuous``: the word's quaternions are already continuous in time
        (``canonical_hemisphere``, as the daemon's model thread makes a whole batch at once)."""
        self._words[end] = restyled if continuous else rot.canonical_hemisphere(np.asarray(restyled, dtype=np.float64))

    def add_words(self, ends, restyled: np.ndarray) -> None:
        """``add_word`` for a batch (N,) / (N, T, J, 4) in one vectorised pass."""
        for end, word in zip(ends, rot.canonical_hemisphere(np.asarray(restyled, dtype=np.float64), axis=1)):
            self._words[int(end)] = word

    def serving_word(self, t: int) -> int:
        """End frame of the word that serves frame t (the first grid end >= t)."""
        return serving_word_end(t, self.settings.hop, self.settings.word_length, self.phase)

    def render(self, t: int, input_rotations: np.ndarray, intensity: float = 1.0, active: bool = True) -> np.ndarray:
        """Output rotations (J, 4) for frame t, given that frame's input rotations."""
        return self.render_block(t, np.asarray(input_rotations)[None], intensity, active)[0]

    def render_block(self, t0: int, inputs: np.ndarray, intensity: float = 1.0, active: bool = True) -> np.ndarray:
        """Output rotations (n, J, 4) for frames t0 .. t0+n-1 given their inputs (n, J, 4).

        Two passes: the first (``plan_block``) walks the runs (one per serving word) and
        carries the blender's state from run to run with work the size of one pose per
        run; the second (``render_planned``) renders every frame of the block in a few
        vectorised operations. A whole clip costs a handful of array operations, not a
        handful per word."""
        inputs = np.asarray(inputs, dtype=np.float64)
        return render_planned([(self, self.plan_block(t0, inputs, intensity, active), inputs)])[0]

    def plan_block(self, t0: int, inputs: np.ndarray, intensity: float = 1.0, active: bool = True) -> list:
        """``render_block``'s first pass: the blender's state moves on over frames
        t0 .. t0+n-1 and the runs to render are returned (``render_planned`` renders the
        runs of many blenders at once: the daemon's performers of a tick)."""
        runs = self._plan(t0, np.asarray(inputs, dtype=np.float64), intensity, active)
        self._forget_before(self.serving_word(t0 + len(inputs) - 1))
        return runs

    def _plan(self, t0: int, inputs: np.ndarray, intensity: float, active: bool) -> list:
        """Pass 1: per run (start, length, restyle, mix), the state carried to the next."""
        runs, t, n = [], t0, len(inputs)
        while t < t0 + n:
            end = self.serving_word(t)
            run = min(end, t0 + n - 1) - t + 1  # frames served by this word in the block
            # A word ending at frame e serves frames from e + 1 - hop on, which are rendered
            # from time e + 1 + (delay - hop) on: the model has delay - hop + 1 frame
            # periods, the first word as much as any.
            word = self._words.get(end)
            if word is None and active:
                self.late_frames += run  # should have arrived: fade out, never stall
            start = t - t0
            restyle = self._plan_restyle(t, end, word, inputs[start + run - 1], run)
            runs.append((start, run, restyle, self._plan_mix(run, word is not None and active, intensity)))
            t += run
        return runs

    def _plan_restyle(self, t: int, end: int, word: np.ndarray | None, last_input: np.ndarray, n: int) -> tuple:
        """How a run's restyled poses are made, and the state after its last frame:
        ("residual", r): r * input while no word serves; ("word", frames, offset, c2):
        the word's frames under the seam spring's offset (see ``_spring``)."""
        if word is None:
            if self._serving is not None and self._last_restyled is not None:
                self._residual = rot.multiply(_pose(self._last_restyled), rot.inverse(self._last_input))
            self._serving = None
            self._shown = ("rotation", self._residual, last_input)
            return ("residual", self._residual)
        index = self._frame_in_word(t, end)
        if self._omega == 0.0:
            self._offset = np.zeros_like(self._offset)
        elif end != self._serving and self._shown is not None and index > 0:
            # Switch of word: carry the new word onto what was shown a frame ago.
            # The offset's velocity carries over, so the motion does not kink either.
            self._offset = rot.log_map(rot.multiply(_pose(self._shown), rot.inverse(word[index - 1])))
        self._serving = end
        offset, c2 = self._offset, self._offset_velocity + self._omega * self._offset
        self._offset, self._offset_velocity = _spring(offset, self._offset_velocity, self._omega, n)
        self._shown = ("offset", self._offset, word[index + n - 1])
        self._last_restyled, self._last_input = self._shown, last_input
        return ("word", word[index:index + n], offset, c2)

    def _frame_in_word(self, t: int, end: int) -> int:
        """Frame t's index in the word that ends at frame ``end``."""
        return t - (end - self.settings.word_length + 1)

    def _plan_mix(self, n: int, available: bool, intensity: float):
        """Move ``mix`` towards its target by at most one crossfade step per frame:
        1.0 (restyled), 0.0 (input) or the per-frame mix (n,) to slerp with."""
        target = min(max(float(intensity), 0.0), 1.0) if available else 0.0
        if self._first_frame:
            self._first_frame = False
            if self.settings.start_restyled:
                self.mix = target
        if self.mix == target and target in (0.0, 1.0):  # the common, settled case
            return target
        step = 1.0 / self.settings.crossfade_frames
        ramp = step * np.arange(1, n + 1)
        mix = np.minimum(target, self.mix + ramp) if target > self.mix else np.maximum(target, self.mix - ramp)
        self.mix = float(mix[-1])
        if np.all(mix >= 1.0):
            return 1.0
        if np.all(mix <= 0.0):
            return 0.0
        return mix

    def _forget_before(self, end: int) -> None:
        for old in [e for e in self._words if e < end]:
            del self._words[old]


def plan_frames(items: list[tuple[SeamBlender, int, np.ndarray, float, bool]]) -> list[list]:
    """``plan_block`` of one frame for each of many blenders, (blender, t, input (J, 4),
    intensity, active) -> each one's planned runs, as ``plan_block(t, input[None],
    intensity, active)`` plans them: the daemon's tick. The blenders' seam springs step on
    together and their switches of word are computed together, in a few array operations
    for all; per blender, one spring step and a switch every ``hop`` frames cost ~48 us
    (numpy's per-call cost on (J, 3) arrays), 3 ms a tick at 64 performers here. A
    blender with no word to serve this frame, or with blending off, plans on its own."""
    planned: list = [None] * len(items)
    served: list[_ServedFrame] = []
    for k, (blender, t, inputs, intensity, active) in enumerate(items):
        end = blender.serving_word(t)
        word = blender._words.get(end)
        if word is None or blender._omega == 0.0:
            planned[k] = blender.plan_block(t, inputs[None], intensity, active)
        else:
            index = blender._frame_in_word(t, end)
            served.append(_ServedFrame(k, blender, inputs, intensity, active, word, index, end))
    if not served:
        return planned
    # Switches of word: carry the new word onto what was shown a frame ago (``_plan_restyle``).
    switching = [f for f in served if f.end != f.blender._serving and f.blender._shown is not None and f.index > 0]
    if switching:
        before = np.stack([f.word[f.index - 1] for f in switching])
        offsets = rot.log_map(rot.multiply(_poses([f.blender._shown for f in switching]), rot.inverse(before)))
        for f, offset in zip(switching, offsets):
            f.blender._offset = offset
    offset = np.stack([f.blender._offset for f in served])
    velocity = np.stack([f.blender._offset_velocity for f in served])
    omega = np.array([f.blender._omega for f in served])[:, None, None]
    c2 = velocity + omega * offset
    after, after_velocity = _spring(offset, velocity, omega, 1)
    for i, f in enumerate(served):
        b = f.blender
        b._serving = f.end
        b._offset, b._offset_velocity = after[i], after_velocity[i]
        b._shown = b._last_restyled = ("offset", after[i], f.word[f.index])
        b._last_input = f.inputs
        restyle = ("word", f.word[f.index:f.index + 1], offset[i], c2[i])
        planned[f.item] = [(0, 1, restyle, b._plan_mix(1, f.active, f.intensity))]
        b._forget_before(f.end)
    return planned


class _ServedFrame(NamedTuple):
    """A frame ``plan_frames`` plans from a word: the item's place, its blender and input,
    intensity and activity, and the word (ending at ``end``) with the frame's index in it."""

    item: int
    blender: SeamBlender
    inputs: np.ndarray
    intensity: float
    active: bool
    word: np.ndarray
    index: int
    end: int


def planned_mix(runs: list, n: int) -> np.ndarray:
    """The share of the restyle shown in each of the ``n`` frames ``plan_block`` planned as
    ``runs`` (n,): 0 in pass-through, 1 fully restyled, in between through a fade."""
    mix = np.empty(n)
    for start, run, _, m in runs:
        mix[start:start + run] = m
    return mix


def render_planned(items: list[tuple[SeamBlender, list, np.ndarray]]) -> list[np.ndarray]:
    """``render_block``'s second pass for one or many blenders: (blender, its planned runs,
    their inputs (n, J, 4)) -> output rotations (n, J, 4) each, every frame of every item
    in a few vectorised operations (the daemon renders one frame of each performer a
    tick: one call for all of them, where numpy's per-call cost was most of the work)."""
    inputs = np.concatenate([np.asarray(i, dtype=np.float64) for _, _, i in items])
    bases = np.cumsum([0] + [len(i) for _, _, i in items])
    runs = [(blender, base + start, n, restyle, mix)
            for (blender, planned, _), base in zip(items, bases) for start, n, restyle, mix in planned]
    out = inputs.copy()
    from_words = [r for r in runs if r[3][0] == "word" and not _is_input(r[4])]
    if from_words:
        lengths = [n for _, _, n, _, _ in from_words]
        frames = np.concatenate([restyle[1] for _, _, _, restyle, _ in from_words])
        k = np.concatenate([np.arange(1, n + 1, dtype=np.float64) for n in lengths])[:, None, None]
        offset = np.repeat(np.stack([restyle[2] for _, _, _, restyle, _ in from_words]), lengths, axis=0)
        c2 = np.repeat(np.stack([restyle[3] for _, _, _, restyle, _ in from_words]), lengths, axis=0)
        omega = np.repeat([blender._omega for blender, _, _, _, _ in from_words], lengths)[:, None, None]
        at = np.concatenate([np.arange(start, start + n) for _, start, n, _, _ in from_words])
        out[at] = rot.multiply(rot.exp_map(_spring_at(offset, c2, omega, k)), frames)
    for _, start, n, restyle, mix in runs:
        if restyle[0] == "residual" and not _is_input(mix):
            out[start:start + n] = rot.multiply(restyle[1], inputs[start:start + n])
    blends = [r for r in runs if not np.isscalar(r[4])]
    if blends:
        at = np.concatenate([np.arange(start, start + n) for _, start, n, _, _ in blends])
        mix = np.concatenate([mix for _, _, _, _, mix in blends])
        out[at] = rot.slerp(inputs[at], out[at], np.broadcast_to(mix[:, None], out[at].shape[:2]))
    return [out[lo:hi] for lo, hi in zip(bases[:-1], bases[1:])]


class Restyled(NamedTuple):
    """A restyled stream: rotations (T, J, 4), and root positions (T, 3) where the roots
    were given (the foot lock moves the pelvis height; without it they are the input's)."""

    rotations: np.ndarray
    roots: np.ndarray | None


def restyle_stream(rotations: np.ndarray, restyle_words, settings: BlendSettings,
                   intensity: float = 1.0, batch: int = 64, roots: np.ndarray | None = None,
                   feet=None, first: int = 0) -> Restyled:
    """Offline: run a whole clip's humanoid rotations (T, J, 4) through the same cutter and
    blender the daemon uses, with every word restyled in time (never late).

    The end of the clip is treated as a live source that stops: its last frame is held
    (repeated) until a word covers the final real frame, exactly as the daemon holds a
    stalled source. ``restyle_words`` maps words (B, 60, J, 4) to restyled words of the
    same shape; batching does not change the result because words are independent.
    The blended output's correction is low-passed (``smoothing.CorrectionFilter``), its
    elbows and knees kept to their hinges (``hinges.keep_hinges``), then ``feet``, a
    ``footlock.FootLock`` (with the clip's root positions ``roots`` (T, 3)), keeps planted
    feet where the input put them and sets the pelvis height: the daemon's order, frame
    by frame. ``first``: frames cut into words but never shown (the held copy a half-rate
    stream starts with, ``half_rate_shift``): rendering starts after them, as the daemon's,
    and the result is the frames from ``first`` on.
    """
    T, J = rotations.shape[:2]
    blender = SeamBlender(settings, J)
    held = max(blender.serving_word(T - 1) - (T - 1), 0)
    padded = np.concatenate([rotations, np.repeat(rotations[-1:], held, axis=0)])
    ends, words = cut_words(padded, settings.hop, settings.word_length, settings.phase)
    for i in range(0, len(words), batch):
        blender.add_words(ends[i:i + batch], restyle_words(words[i:i + batch]))
    shown = rotations[first:]
    runs = blender.plan_block(first, shown, intensity)
    out = CorrectionFilter(J, settings.correction_tau).apply(shown, render_planned([(blender, runs, shown)])[0])
    out = keep_hinges(shown, out)
    if feet is None:
        return Restyled(out, None if roots is None else roots[first:])
    # The daemon holds an ended source's last frame for at least ``delay`` >= ramp frames.
    # The lock counts the shown frames: the ``first`` are not its (as the daemon's).
    tail = max(held, feet.ramp)
    feet.push(np.concatenate([roots[first:], np.repeat(roots[-1:], tail, axis=0)]),
              np.concatenate([shown, np.repeat(rotations[-1:], tail, axis=0)]))
    new_roots, locked = feet.apply(0, roots[first:], shown, out, planned_mix(runs, T - first))
    return Restyled(locked, new_roots)
