"""One performer's stream: input ring, motion words, seam blender, one output frame per tick.

The algorithm is ``motion.words`` (WordCutter + SeamBlender), the very code offline
``stylecast restyle`` runs through ``restyle_stream``; this module only adds what a live
stream needs around it:

* Rate and time: a source stamps frames in its own time base at its own rate; the
  session's ``StreamResampler`` puts them on the 60 Hz output grid (slerp) and a fixed
  offset maps source time onto the daemon clock. A source at half the output rate
  brings its frames in pairs; where every word can end on a source frame (an even hop,
  after a held copy of the first frame: ``words.half_rate_shift``) it is shown ``delay``
  frames after each frame's own time like a 60 Hz one, else a frame behind each pair.
* Frame indices count (resampled) input frames in arrival order. Output frame t is rendered ``delay``
  frames after input frame t arrived (the blender's latency model), one frame per tick
  of the daemon's 60 Hz output clock.
* Jitter: a tick that brings two input frames and one that brings none even out (the
  output index lags the newest input by ``delay`` plus at most ``MAX_LAG`` frames). A
  source running steadily fast is caught up by skipping frames (counted).
* A lag that outlives the jitter (a source that sent a burst, ticks the machine
  dropped) costs latency for good unless it is worked off: after ``LAG_PATIENCE`` ticks
  behind, or at once for ticks the engine dropped, the session skips input frames until
  it is back at exactly ``delay`` frames.
* Stall: when no new input arrives the session re-sends its last output frame (counted
  as held): the avatar holds instead of freezing the clock or jumping.
* Bypass and (re)activation: in bypass no words are cut for the model (saves the CPU);
  when bypass ends, frames whose serving word was cut before are shown as pass-through
  without counting them late, and the blender fades the restyle back in.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from stylecast.motion.clip import PoseFrame
from stylecast.motion.clock import OUTPUT_FPS
from stylecast.motion.footlock import ContactSettings, FootLock, LockJob, plan_locks, push_frames, solve_lock_jobs
from stylecast.motion.hinges import keep_hinges
from stylecast.motion.resample import StreamResampler
from stylecast.motion.skeleton import Skeleton
from stylecast.motion.smoothing import CorrectionFilter, filter_frames
from stylecast.motion.words import (BlendSettings, SeamBlender, WordCutter, half_rate_shift, plan_frames,
                                   planned_mix, render_planned)

from .status import LatencyWindow

MAX_LAG = 3  # frames of jitter absorbed before skipping ahead
LOST_AFTER = 60  # ticks without new input (1 s) before the performer is reported lost
LAG_PATIENCE = 30  # ticks a session may run behind its delay before it drops one frame


@dataclass(frozen=True, eq=False)
class OutputFrame:
    performer: str
    index: int  # input/output frame index t
    arrival: float  # when input frame t arrived, on the daemon clock
    root_position: np.ndarray  # (3,) cm: the input's, at the pelvis height the foot lock set
    rotations: np.ndarray  # (J, 4) restyled (blended) local rotations
    input_rotations: np.ndarray  # (J, 4) what came in (for --out-input)
    input_root: np.ndarray  # (3,) cm, what came in


@dataclass(eq=False)
class PendingFrame:
    """A new output frame from ``Session.begin_render`` to ``finish_render``, to be planned
    by the seam blender, rendered, low-passed and foot-locked with the other performers'
    frames of the tick (``settle_frames``)."""

    index: int
    arrival: float
    input_root: np.ndarray
    input_rotations: np.ndarray  # (J, 4)
    intensity: float
    active: bool  # restyled words may be shown (not bypassed or resuming)
    runs: list | None = None  # the seam blender's plan (``plan_frames``)
    lock: LockJob | None = None  # the foot lock's job, solved


def push_feet(sessions: list) -> None:
    """The input frames the sessions ingested since the last call into their foot locks'
    contact detection, the legs of all of them in one vectorised pass (``push_frames``)."""
    rows = [(session.feet, root, rotations) for session in sessions for root, rotations in session._feet_frames]
    for session in sessions:
        session._feet_frames = []
    push_frames(rows)


def settle_frames(sessions: list["Session"], pending: list[PendingFrame]) -> None:
    """The rest of one new frame of each session, each stage one vectorised pass over all
    of them: the seam blender's plan and render, the correction low-pass, the elbows and
    knees kept to their hinges (``hinges.keep_hinges``), then the foot lock and the pelvis
    height. Sets each pending frame's ``runs`` and ``lock`` (its solved job)."""
    if not pending:
        return
    planned = plan_frames([(s.blender, p.index, p.input_rotations, p.intensity, p.active)
                           for s, p in zip(sessions, pending)])
    for frame, runs in zip(pending, planned):
        frame.runs = runs
    inputs = np.stack([p.input_rotations for p in pending])
    blended = render_planned([(s.blender, p.runs, inputs[k:k + 1]) for k, (s, p) in enumerate(zip(sessions, pending))])
    smoothed = keep_hinges(inputs, filter_frames([s.smoothing for s in sessions], inputs, np.concatenate(blended)))
    # The foot lock counts the source's frames: a held first frame is never shown, nor pushed to it.
    jobs = plan_locks([(s.feet, p.index - s.held_first, p.input_root, p.input_rotations, smoothed[k],
                        planned_mix(p.runs, 1))
                       for k, (s, p) in enumerate(zip(sessions, pending))])
    for frame, job in zip(pending, jobs):
        frame.lock = job
    solve_lock_jobs(jobs)


class Session:
    def __init__(self, index: int, source, settings: BlendSettings, skeleton: Skeleton, phase: int | None = None,
                 contacts: ContactSettings = ContactSettings()):
        self.index = index
        self.source = source
        self.performer = source.performer
        self.settings = settings  # shared with the daemon and every session: never copied
        self.phase = settings.phase if phase is None else phase
        # The model thread makes the tick's words continuous, all in one pass (inference.py).
        self.cutter = WordCutter(settings.hop, settings.word_length, self.phase, continuous=False)
        self.blender = SeamBlender(settings, len(skeleton), phase=self.phase)
        # Planted feet of the input stay planted in the output (after the blender, as
        # offline ``restyle`` does); it looks ahead into the ``delay`` frames buffered.
        self.feet = FootLock.for_stream(skeleton, settings.delay, contacts, fade_in=settings.first_fade_end,
                                        fade_tau=settings.correction_tau)
        self._feet_frames: list = []  # (root, rotations) ingested, for the tick's one ``push_feet``
        self.smoothing = CorrectionFilter(len(skeleton), settings.correction_tau)
        self._inputs: deque = deque(maxlen=settings.delay + MAX_LAG + 2)  # (t, arrival, root, rot)
        self.frames_in = 0
        self.out_t: int | None = None  # next output frame index
        self.last_output: OutputFrame | None = None
        self._intensity = 1.0
        self.bypass = False
        # Style mix of a multi-style model (None: the model's own). A change moves the mix
        # from where it is to the new one over the crossfade, frame by frame; each word is
        # restyled with the mix of the frame that completed it, so the style turns
        # gradually word by word and the seam blender joins the words (no jump).
        self._style_from: np.ndarray | None = None
        self._style_to: np.ndarray | None = None
        self._style_progress = 1.0
        self.style_label = ""
        self._resume_end = 0  # words ending before this were never cut for the model
        # counters
        self.frames_out = 0
        self.held = 0
        self.dropped = 0  # output ticks the overloaded machine missed
        self.held_run = 0  # consecutive ticks held (source silent)
        self.pending_skip = 0  # input frames to skip to make up for dropped ticks
        self._lag_ticks = 0
        self.new_frame = False  # did the last render produce a new frame (not a hold)
        self.skipped = 0
        self.words = 0
        self.words_failed = 0
        self.latency = LatencyWindow()
        self.skeleton = getattr(source, "skeleton", None)
        self.skeleton_changed = False
        # Sources run at their own rate and time base; the session puts every stream on
        # the output rate (drivers never resample).
        self.resampler = StreamResampler(OUTPUT_FPS)
        self._clock_offset: float | None = None
        self._burst = 0  # frames the last ingest brought
        # A half-rate source (30 fps) whose word ends all fall on its own frames is shown a
        # period sooner (``words.half_rate_shift``): ``lead`` 1, after ``held_first`` held
        # copies of its first frame. Decided on the first source frame after the stream's
        # first that brings grid frames, and again after each restart of its time base
        # (``held_realigned`` counts the held frames such a restart took to realign it).
        self._rate_pending = False
        self.lead = 0
        self.held_first = 0
        self.held_realigned = 0

    @property
    def intensity(self) -> float:
        return self._intensity

    @intensity.setter
    def intensity(self, value: float) -> None:
        # A stream's first fade-in takes its stance at the share it heads for (``StanceOffset.aim``).
        self._intensity = self.feet.stance.aim = float(value)

    # -- input side -------------------------------------------------------------------

    def ingest(self, now: float) -> list[tuple[int, np.ndarray]]:
        """Pull the source's new frames; return the words (end, word) they completed.

        A source that has ended is held: its last frame is pushed again once per tick
        until the output has passed the last real frame, so the words that serve the
        final frames are cut from real motion plus a held pose, exactly as offline
        ``restyle_stream`` pads a clip's end."""
        words = []
        before = self.cutter.frames_seen
        for frame in self.source.poll(now):
            restarts = self.resampler.restarts
            grid = self.resampler.feed(frame)
            anchored = self.resampler.restarts != restarts or not self.cutter.frames_seen
            if anchored:
                self._rate_pending = True  # a grid's anchor: the rate is learnt after it
            elif self._rate_pending and grid:
                words += self._learn_rate(grid)
            elif self.lead and grid and not self._ends_pair(grid):
                self.lead = 0  # an irregular sender: word ends may fall between its frames
            for grid_frame in grid:
                words += self.push(self._on_daemon_clock(grid_frame, now, restarts))
            if anchored and self.lead and self._off_parity():
                # A half-rate stream restarted (a pause, the sender's clock replaced): its anchor
                # held once more at once keeps the frames' count and the word ends' parity, where
                # waiting for the next frame to tell the rate would cost a held tick and a skip.
                words += self._hold_anchor()
        self._burst = self.cutter.frames_seen - before
        self._check_skeleton()
        if self.source.finished and self._inputs and self.cutter.frames_seen < self.stream_frames + self.settings.delay:
            _, arrival, root, rotations = self._inputs[-1]
            words += self.push(PoseFrame(self.performer, arrival, root, rotations), held=True)
        return words

    def _ends_pair(self, grid: list) -> bool:
        # The source frame is the last grid frame it brings (the resampler snapped it), at
        # an index of the word ends' parity (``lead`` is only ever set where they have one).
        index = self.cutter.frames_seen + len(grid) - 1
        return self.resampler.snapped and (index - self._end_parity()) % 2 == 0

    def _end_parity(self) -> int | None:
        return half_rate_shift(self.settings.hop, self.settings.word_length, self.phase)

    def _off_parity(self) -> bool:
        # The frame last pushed, a source frame, is not at the word ends' parity.
        return (self.cutter.frames_seen - 1 - self._end_parity()) % 2 != 0

    def _learn_rate(self, grid: list) -> list[tuple[int, np.ndarray]]:
        # The first source frame after the grid's anchor that brings grid frames: at half the
        # output rate it brings two, the second on the grid at its own time. Its frames then
        # fall on every other index from the anchor's, the source frame last pushed; where
        # that is not the word ends' parity, the anchor is held once more.
        self._rate_pending = False
        half_rate = len(grid) == 2 and self.resampler.snapped and self._end_parity() is not None
        self.lead = int(half_rate)
        if not (half_rate and self._off_parity()):
            return []
        return self._hold_anchor(start=self.cutter.frames_seen == 1)

    def _hold_anchor(self, start: bool = False) -> list[tuple[int, np.ndarray]]:
        # The anchor held once more, to set a half-rate stream's frames on the word ends.
        if start:
            # The stream's first frame (``held_first``): never shown, and not the foot lock's: a
            # frame standing still would read as a contact there, and a foot in the air at the
            # start would set a floor the lock then drops (a popped knee).
            self.held_first = 1
        else:
            # After a restart (``held_realigned``): shown, and the foot lock sees it as shown
            # (the output holds through a pause anyway).
            self.held_realigned += 1
        _, arrival, root, rotations = self._inputs[-1]
        return self.push(PoseFrame(self.performer, arrival, root, rotations), held=True, feet=not start)

    @property
    def stream_frames(self) -> int:
        """Frames of the stream that came from the source: ``frames_in``, and the held copies
        that set a half-rate source's frames on the word ends (``held_first``, ``held_realigned``)."""
        return self.frames_in + self.held_first + self.held_realigned

    def _on_daemon_clock(self, frame: PoseFrame, now: float, restarts: int) -> PoseFrame:
        # Source time -> daemon time by a fixed offset taken when the stream (re)starts:
        # the frame's arrival for the latency figures. Jitter and drift are the ring's job
        # (MAX_LAG, LAG_PATIENCE), not the timestamps'.
        if self._clock_offset is None or self.resampler.restarts != restarts:
            self._clock_offset = now - frame.timestamp
        return PoseFrame(self.performer, frame.timestamp + self._clock_offset, frame.root_position, frame.rotations)

    def _check_skeleton(self) -> None:
        # The source contract: ``source.skeleton`` is the performer's proportions as last
        # learnt (a VMC sender's bone offsets, a tracker calibration); a new object is a
        # change, which the daemon passes on to the sinks.
        skeleton = getattr(self.source, "skeleton", None)
        if skeleton is not None and skeleton is not self.skeleton:
            self.skeleton = skeleton
            self.skeleton_changed = True
            push_feet([self])  # the frames before the change on the legs they came with
            self.feet.set_offsets(skeleton.offsets)  # the lock's legs are the performer's

    def push(self, frame: PoseFrame, held: bool = False, feet: bool = True) -> list[tuple[int, np.ndarray]]:
        t = self.cutter.frames_seen
        rotations = np.asarray(frame.rotations, dtype=np.float64)
        root = np.asarray(frame.root_position, np.float64)
        self._inputs.append((t, float(frame.timestamp), root, rotations))
        if feet:
            self._feet_frames.append((root, rotations))  # contacts: ``push_feet``, once a tick for all
        if not held:
            self.frames_in += 1
        if self._style_progress < 1.0:
            p = self._style_progress + 1.0 / self.settings.crossfade_frames
            self._style_progress = 1.0 if p > 1.0 - 1e-9 else p  # sums of 1/n fall short of 1 by rounding
        out = self.cutter.push(rotations)
        if out is None or self.bypass:
            return []
        self.words += 1
        return [out]

    def set_style(self, weights: np.ndarray | None, label: str = "", own: np.ndarray | None = None) -> None:
        """Crossfade to the style mix ``weights`` from the mix in use (``own``: the model's,
        when this performer has not chosen one). None: back to the model's own, at once
        (a model without style codes was loaded)."""
        if weights is None:
            self._style_from = self._style_to = None
            self._style_progress, self.style_label = 1.0, ""
            return
        current = self.style_weights()
        if current is None:
            current = np.asarray(weights if own is None else own, np.float64)
        self._style_from = current
        self._style_to = np.asarray(weights, np.float64)
        self._style_progress = 0.0
        self.style_label = label

    @property
    def style_target(self) -> np.ndarray | None:
        """The mix this performer chose, where its crossfade goes (None: the model's own)."""
        return self._style_to

    def style_weights(self) -> np.ndarray | None:
        """The mix words are restyled with now (None: the model's own)."""
        if self._style_to is None:
            return None
        p = self._style_progress
        return self._style_to if p >= 1.0 else (1.0 - p) * self._style_from + p * self._style_to

    def set_delay(self, delay: int) -> None:
        """A new delay (the engine's slack planner). Longer: the output holds until it is
        reached. Shorter: the session is behind by the difference and works it off by
        skipping input frames, one per ``LAG_PATIENCE`` ticks as for any lag that lasts.
        The input ring never shrinks: the frames it must still show lag the newest by the
        old delay."""
        self.settings.delay = delay
        if delay + MAX_LAG + 2 > self._inputs.maxlen:
            self._inputs = deque(self._inputs, maxlen=delay + MAX_LAG + 2)

    def set_bypass(self, bypass: bool) -> None:
        if self.bypass and not bypass:
            # The next word the model will see is the next one the cutter emits.
            self._resume_end = self.blender.serving_word(self.cutter.frames_seen)
        self.bypass = bypass

    def add_word(self, end: int, restyled: np.ndarray, continuous: bool = False) -> None:
        self.blender.add_word(end, restyled, continuous)

    # -- output side ------------------------------------------------------------------
    def render(self, drain: bool = False) -> OutputFrame | None:
        """The output frame for this tick: a new one, the held last one, or None before
        the first ``delay`` frames have arrived. ``drain`` (the source has ended): its
        held frames (see ``ingest``) carry the last ``delay`` real frames out, and nothing
        past the last real frame is sent. The engine runs the halves itself (``begin_render``,
        ``settle_frames``, ``finish_render``), so one ``settle_frames`` serves every
        performer of the tick."""
        step = self.begin_render(drain)
        if not isinstance(step, PendingFrame):
            return step
        settle_frames([self], [step])
        return self.finish_render(step)

    def begin_render(self, drain: bool = False) -> "PendingFrame | OutputFrame | None":
        """``render`` up to the seam blender: a new frame is returned pending (for
        ``settle_frames``), anything else as ``render`` returns it."""
        newest = self.cutter.frames_seen - 1
        # The lead shortens the foot lock's look-ahead by a frame: only where its sight (at
        # most its ramp) is short of the delay, so the lock reads what it did without it.
        lead = self.lead if self.feet.sight < self.settings.delay else 0
        target = newest - self.settings.delay + lead
        if drain:
            target = min(target, self.stream_frames - 1)
        self.new_frame = False
        if target < 0:
            return None
        if self.out_t is None:
            # A source slower than the output clock (30 Hz), or not a multiple of it
            # (90 Hz), delivers resampled frames in bursts (two, then none). Start as far
            # behind the newest frame as this tick's burst, so the output steps one frame
            # per tick from the start instead of holding on the tick after the burst. A
            # held copy of a stream's first frame is shown instead of the first frame.
            start = target - min(max(self._burst - 1, 0), MAX_LAG)
            if start < self.held_first:
                return None
            self.out_t = start
        elif not drain:
            behind = target - self.out_t
            self._lag_ticks = self._lag_ticks + 1 if behind > 0 else 0
            skip = behind if behind > MAX_LAG else min(behind, self.pending_skip)
            if skip <= 0 and self._lag_ticks > LAG_PATIENCE:
                skip = 1
            if skip > 0:
                self.skipped += skip
                self.out_t += skip
                self._lag_ticks = 0
            self.pending_skip = 0
        if self.out_t > target:
            if not drain:
                self.held += 1
                self.held_run += 1
            return self.last_output
        self.held_run = 0
        t = self.out_t
        _, arrival, root, input_rot = self._input(t)
        active = (not self.bypass) and self.blender.serving_word(t) >= self._resume_end
        self.out_t = t + 1
        self.frames_out += 1
        return PendingFrame(t, arrival, root, input_rot, self.intensity, active)

    def finish_render(self, pending: PendingFrame) -> OutputFrame:
        """The frame ``begin_render`` left pending, settled (``settle_frames``)."""
        job = pending.lock
        frame = OutputFrame(self.performer, pending.index, pending.arrival, job.new_roots[0], job.result[0],
                            pending.input_rotations, pending.input_root)
        self.last_output = frame
        self.new_frame = True
        return frame

    def _input(self, t: int):
        # The ring holds the last delay + MAX_LAG + 2 frames and t lags the newest by at
        # most delay + MAX_LAG, so t is always there; index from the right end.
        item = self._inputs[t - self._inputs[-1][0] - 1]
        assert item[0] == t
        return item

    @property
    def lost(self) -> bool:
        """The source has been silent for a second (or never sent): shown in the status."""
        return self.held_run >= LOST_AFTER or (self.frames_in == 0 and not self.source.finished)

    def counters(self) -> dict:
        return {
            "performer": self.performer, "frames_in": self.frames_in, "frames_out": self.frames_out,
            "late": self.blender.late_frames, "held": self.held, "skipped": self.skipped,
            "dropped": self.dropped, "lost": self.lost,
            "words": self.words, "words_failed": self.words_failed,
            "intensity": self.intensity, "bypass": self.bypass, "mix": round(self.blender.mix, 3),
            "style": self.style_label,
            "latency_p50_ms": self.latency.percentile(50) * 1e3,
            "latency_p99_ms": self.latency.percentile(99) * 1e3,
            **{f"source_{k}": v for k, v in self.source.counters().items()},
        }
