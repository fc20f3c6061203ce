"""The daemon: sources -> sessions -> batched inference -> 60 Hz output clock -> sinks.

Latency model (``motion.words`` has the derivation):

* Input frame t of a performer arrives at time a(t). Every ``hop`` frames a 60-frame word
  ending at e is cut the moment frame e arrives and goes to the inference worker.
* The output clock ticks at T0 + k/60. At each tick every session renders exactly one
  frame: output frame t leaves on the tick ``delay`` frames after input frame t arrived
  (delay >= hop, default hop), so the added latency is delay/60 s plus the processing
  time of the tick (a replayed source arrives on the ticks themselves).
* The word ending at e is first needed delay - hop + 1 ticks after frame e arrived (the
  model's *slack*). The slack is chosen so words are on time (``daemon.latency``): the
  model is timed before the clock starts, and the delay is raised, with one status line,
  when the measured time from a tick to its results no longer fits. A word that is
  still not back in time is *late*: the blender fades that stretch to pass-through and
  blends back in when words return (counted per performer as late frames). The output
  clock never waits for the model.
* A tick that starts late (machine busy) still goes out, as soon as possible; a tick
  more than ``MAX_BACKLOG_TICKS`` periods late is dropped instead of bunched: its output
  frames are counted as dropped, the sessions skip the matching input frames, and the
  clock stays on its grid (no drift, no growing latency).

Per tick, in this order (the order is what makes fake-clock replays exact):
  1. apply queued control commands, swap in a newly loaded model;
  2. collect finished inference results (under a virtual clock: wait for all of them);
  3. poll every source and cut words; submit this tick's words as ONE batch;
  4. render one frame per session (the seam blender's plan and render, the correction
     low-pass and the foot lock of all sessions in one vectorised pass each) and emit the
     frames to their sinks (VMC, input VMC: the values of all in one pass; recorder);
  5. every ``status_interval`` seconds, log one status line per performer.
"""

from __future__ import annotations

import gc
import logging
import math
import threading

from stylecast.motion.clock import Clock
from stylecast.motion.errors import UserError
from stylecast.motion.footlock import amplitudes_of, feet_for, pace_of, quick_hips_of, stance_standing_of
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default
from stylecast.motion.words import BlendSettings, stream_settings_of

from .commands import apply_command
from .config import FPS, DaemonConfig
from .control import ControlServer
from .inference import InferenceWorker
from .latency import MAX_SLACK, calibrate, delay_line, lowered_line, slack_for
from .output import PerformerSinks, emit_frames, open_outputs, recording_path
from .restylers import (load_restyler, model_name, style_label, style_mix, warm_up, with_direction,
                        with_performer_style, with_style)
from .session import PendingFrame, Session, push_feet, settle_frames
from .status import LatencyWindow, status_line, status_messages

log = logging.getLogger("stylecast.daemon")
STATUS_REPLIES_PER_TICK = 4  # bounds the work a status-request flood can cause
CONTROL_ERRORS_LOGGED = 10  # refused commands logged one by one; after that every 1000th
MAX_BACKLOG_TICKS = 2  # a tick this many periods late (33 ms) is dropped, not sent late


# Performers whose words share one model call. Groups of 4 were tried (2026-11-29, a
# 16-performer soak over two processes on the Intel Xeon VM, alternated): the calls came
# back sooner (18 ms at worst against 32) and the delay was at 5 frames in 61 % of the
# samples against 14 %, but at 5 the stalls this VM has every few minutes (results 40-56
# ms after their tick) made 8 and 12 frames late in a 10- and a 30-minute run, where
# groups of 8, sitting at 6, had none; the hour-long soak's goal is zero late words,
# so 8 stays (docs/MEASUREMENTS.md).
BATCH_GROUP = 8
PLAN_EVERY_TICKS = 60  # how often the slack planner's estimate is checked (1 s)
# torch's CPU threads for the live model. More than one makes its threads wait on each
# other and on the output loop: on this project's shared 2-core machine, 8 words took
# 575 ms with 2 threads against 11.5 ms with one (issue 12). Batches, not threads, are
# how the live path scales (and worker processes, one per core).
LIVE_TORCH_THREADS = 1
# How long a thread may hold the GIL while another waits for it (Python's default: 5 ms).
# The output loop, the receive thread and the model's worker thread share one GIL, and a
# thread that waits may wait that long at every hand-over. 64 performers over two
# processes (8 s runs, twice): at 1 ms the delay settled at 6 frames (p99 117-119 ms), at
# 5 ms at 7 (134-137 ms); no late word in either.
LIVE_SWITCH_INTERVAL = 0.001


def stagger_phase(hop: int, k: int, performers: int) -> int:
    """Performer k's word-grid phase: its group's share of the hop.

    Performers that start together would hand all their words to the model on one tick
    and wait for one big batch; with delay = hop the model has one frame period, so a
    large batch comes back late (counted, faded to pass-through). Groups of
    ``BATCH_GROUP`` share a phase, and the groups spread evenly over the hop: words are
    still batched, and no tick carries more than a group's worth. The phase is the only
    per-performer setting: every session shares the daemon's one ``BlendSettings``, so a
    live change (``/stylecast/crossfade``) reaches every performer."""
    groups = -(-performers // BATCH_GROUP)
    return (k // BATCH_GROUP) * hop // groups


def worker_offset(hop: int, phases: int, worker: int, workers: int) -> float:
    """Frame periods by which worker process ``worker`` of ``workers`` (``serve --workers``)
    starts its output clock after a grid shared by all of them, so the model calls of
    different processes take turns on the machine's cores instead of landing on the same
    ticks. A process's performer groups take ``phases`` evenly spaced ticks of the hop
    (its sessions' distinct ``stagger_phase``s); the processes' grids are shifted by
    1/``workers`` of that spacing. Worker 0 and a lone daemon: 0. With hop 1
    (``--latency low``) every call falls on every tick and the shift is a fraction of a
    period."""
    return worker * hop / (phases * workers)


def grid_start(now: float, hop: int, offset: float) -> float:
    """The first output tick of a worker: the next multiple of ``hop`` frame periods on the
    machine's monotonic clock (shared by every process), plus ``offset`` periods."""
    grid = hop / FPS
    return (math.floor(now / grid) + 1) * grid + offset / FPS


def _live_process_settings() -> None:
    """Process-wide settings the live path needs (``LIVE_TORCH_THREADS``,
    ``LIVE_SWITCH_INTERVAL``); the daemon owns its process."""
    import sys

    sys.setswitchinterval(LIVE_SWITCH_INTERVAL)
    torch = sys.modules.get("torch")  # only a model that uses torch has imported it
    if torch is not None and torch.get_num_threads() > LIVE_TORCH_THREADS:
        torch.set_num_threads(LIVE_TORCH_THREADS)


def _settle_heap() -> bool:
    """Collect start-up's garbage once and freeze what is left (``gc.freeze``): with torch
    and a model loaded a full collection walks ~200k objects (75-190 ms here), and one
    that comes during the show stalls every thread at once (dropped ticks, late words:
    seen in the first seconds of the capacity runs). Frozen, start-up's objects are never
    walked again; later collections see only what the show allocates. True when done
    (``close`` thaws the heap again)."""
    gc.collect()
    gc.freeze()
    return True


class Daemon:
    def __init__(self, config: DaemonConfig, sources: list, restyler, clock: Clock, *,
                 tap=None, frame_taps=None, model_loader=None, log_status: bool = True,
                 first_index: int = 0, remote=None, worker: tuple[int, int] = (0, 1)):
        """``first_index``: the global index of this daemon's first performer (output ports
        and recording names count from it); ``remote``: a connection to the parent of a
        worker process (``daemon.workers``), which forwards control and asks for status;
        ``worker``: this process's index and the number of worker processes (their output
        clocks take turns, ``worker_offset``)."""
        if not sources:
            raise UserError("no source given; add one such as --source bvh:///path/clip.bvh?loop=1")
        self.config = config.validate()
        self.clock = clock
        # /stylecast/model loads onto the device the daemon was started with.
        self.model_loader = model_loader or (lambda name: load_restyler(name, config.device))
        self.log_status = log_status
        self.settings = BlendSettings(
            hop=config.hop, delay=config.delay or None,
            decay_frames=None if config.decay < 0 else config.decay,
            crossfade_frames=config.crossfade_frames)
        self.sessions: list[Session] = []
        self.sinks: list[PerformerSinks] = []
        if config.direction:
            restyler = with_direction(restyler, config.direction)
        if config.style:
            restyler = with_style(restyler, config.style)
        restyler = with_performer_style(restyler, config.performer_style)
        self._take_stream_settings(restyler)
        self.worker = InferenceWorker(restyler, clock=clock.now)
        self.delay_notes: list[str] = []  # the status lines of delay raises and lowerings (also logged)
        self._configured_delay = self.settings.delay  # the planner never lowers below it
        self.first_index = first_index
        self.process_index, self.process_count = worker  # not ``self.worker``, the model's thread
        self.remote = remote
        self.remote_stopped = False
        self.control: ControlServer | None = None
        self.style = style_label(restyler)
        self.ticks = 0
        self.dropped_ticks = 0
        self._froze_heap = False  # start() froze the heap (``_settle_heap``); close() thaws it
        self.tick_lateness = LatencyWindow()  # how late each tick started (scheduler, load)
        self.control_errors = 0
        self._status_replies = 0
        self._pending_model = None
        self._model_lock = threading.Lock()
        self._loader_busy = False  # one model loader thread at a time (see load_model_async)
        self._requested_model: str | None = None
        self.model_requests_replaced = 0
        self._t0: float | None = None
        self._next_status = 0.0
        try:
            self._open(sources, tap, frame_taps)
        except BaseException:
            self.close()
            raise

    # -- construction -----------------------------------------------------------------
    def _open(self, sources, tap, frame_taps) -> None:
        names = set()
        for k, source in enumerate(sources):
            if source.performer in names:
                raise UserError(f"two sources are called {source.performer!r}; give each a name=... option")
            names.add(source.performer)
            skeleton = source.skeleton if source.skeleton is not None else humanoid_skeleton_default()
            if tuple(skeleton.names) != HUMANOID_BONES:
                raise UserError(f"source {source.performer!r} does not deliver the humanoid skeleton")
            session = Session(k, source, self.settings, skeleton,
                              phase=stagger_phase(self.settings.hop, k, len(sources)),
                              contacts=feet_for(self.config.feet, self.worker.restyler, self.config.pace))
            session.intensity = self.config.intensity
            session.set_bypass(self.config.bypass)
            self.sessions.append(session)
            bundled = self.config.bundled
            self.sinks.append(PerformerSinks(
                skeleton.offsets,
                outputs=open_outputs(self.config.out, self.first_index + k, bundled, tap),
                inputs=open_outputs(self.config.out_input, self.first_index + k, bundled),
                recorder=self._recorder(self.first_index + k, skeleton),
                frame_taps=frame_taps))
        address = self.config.control_address()
        if address is not None:
            self.control = ControlServer(*address, allow=self.config.allow)

    def _recorder(self, k, skeleton):
        if not self.config.record:
            return None
        from stylecast.drivers.bvh.bvh_recorder import BvhRecorder

        return BvhRecorder(recording_path(self.config.record, k), skeleton, FPS)

    # -- the clock ----------------------------------------------------------------------
    def start(self) -> None:
        if not self.clock.virtual:
            _live_process_settings()
            self._calibrate()
            self._froze_heap = _settle_heap()
        self._t0 = self.clock.now()
        if self.process_count > 1 and not self.clock.virtual:
            phases = len({s.phase for s in self.sessions})
            offset = worker_offset(self.settings.hop, phases, self.process_index, self.process_count)
            self._t0 = grid_start(self._t0, self.settings.hop, offset)
        self._next_status = self._t0 + self.config.status_interval
        for s in self.sessions:
            s.source.start(self._t0)

    # -- slack: every word on time (daemon.latency) ----------------------------------------
    @property
    def slack(self) -> int:
        return self.settings.delay - self.settings.hop + 1

    def words_per_tick(self) -> int:
        """The most words one tick hands the model: the performers sharing a word phase."""
        phases = [s.phase for s in self.sessions]  # each session's own (stagger_phase), not the shared setting
        return max(phases.count(p) for p in set(phases))

    def _calibrate(self) -> None:
        """Time the model on one tick's batch before the clock starts; start with a slack
        that covers it (twice over: live, the output loop competes for the CPU)."""
        from .latency import CALIBRATION_FACTOR

        batch = self.words_per_tick()
        try:
            warm_up(self.worker.restyler)  # every direction it may switch to live, not only this one
            seconds = calibrate(self.worker.restyler, batch, len(HUMANOID_BONES), repeats=2)
        except Exception as exc:  # a broken model is the worker's to count, not a startup crash
            log.warning("model timing before start failed (%s); keeping delay %d", exc, self.settings.delay)
            return
        self._raise_slack(slack_for(seconds, CALIBRATION_FACTOR),
                          f"one call on {batch} word(s) takes {seconds * 1e3:.1f} ms")

    def _plan_slack(self) -> None:
        planner = self.worker.planner
        needed = planner.needed_slack()
        if needed is None:
            return
        reason = f"results ready up to {planner.estimate_ms():.1f} ms after their tick"
        if needed > self.slack:
            self._raise_slack(needed, reason)
        elif planner.can_lower(self.slack, self._configured_delay - self.settings.hop + 1):
            self._lower_delay(reason)

    def _lower_delay(self, reason: str) -> None:
        old = self.settings.delay
        self._set_delay(old - 1, lowered_line(reason, old, old - 1), logging.INFO)

    def _raise_slack(self, needed: int, reason: str) -> None:
        if needed <= self.slack:
            return
        capped = needed > MAX_SLACK
        hop, old = self.settings.hop, self.settings.delay
        new = hop - 1 + min(needed, MAX_SLACK)
        if new <= old:
            return
        self._set_delay(new, delay_line(reason, hop, old, new, capped), logging.WARNING)

    def _set_delay(self, delay: int, line: str, level: int) -> None:
        """Every session to ``delay``, with its one status line (kept and logged)."""
        self.settings.delay = delay
        for s in self.sessions:
            s.set_delay(delay)
        self.delay_notes.append(line)
        log.log(level, line)

    def tick_time(self, k: int) -> float:
        return self._t0 + k / FPS

    @property
    def finished(self) -> bool:
        """Every source has ended and every session has shown its last frame."""
        return all(s.source.finished and s.out_t is not None and s.out_t >= s.stream_frames
                   for s in self.sessions)

    def run(self, stop: threading.Event | None = None, duration: float = 0.0) -> None:
        if self._t0 is None:
            self.start()
        while not (stop is not None and stop.is_set()) and not self.finished and not self.remote_stopped:
            if duration and self.ticks / FPS >= duration:
                break
            self.clock.sleep_until(self.tick_time(self.ticks))
            if stop is not None and stop.is_set():
                break
            self.step()
            self._drop_missed_ticks()

    def _drop_missed_ticks(self) -> None:
        if self.clock.virtual:
            return
        latest = math.floor((self.clock.now() - self._t0) * FPS)
        missed = latest - MAX_BACKLOG_TICKS - self.ticks
        if missed > 0:
            self.dropped_ticks += missed
            self.ticks += missed
            for s in self.sessions:
                s.dropped += missed
                s.pending_skip += missed

    # -- one tick -----------------------------------------------------------------------
    def step(self) -> None:
        if self._t0 is None:
            self.start()
        now = self.tick_time(self.ticks)
        self.tick_lateness.add(max(0.0, self.clock.now() - now))
        self._apply_control()
        if self.clock.virtual:
            self.worker.wait_idle()
        done, failed = self.worker.collect()
        for s, end, word in done:
            self.sessions[s].add_word(end, word, continuous=True)  # made so by the worker (inference.py)
        for s, _end in failed:
            self.sessions[s].words_failed += 1
        batch = []
        for session in self.sessions:
            for end, word in session.ingest(now):
                batch.append((session.index, end, word, session.style_weights()))
        push_feet(self.sessions)  # before the batch goes to the model, where each frame once pushed its own
        self.worker.submit(batch, now)
        vmc_time = self.ticks / FPS
        steps = []
        for session, sinks in zip(self.sessions, self.sinks):
            if session.skeleton_changed:  # the performer's own proportions, from now on
                session.skeleton_changed = False
                sinks.set_offsets(session.skeleton.offsets)
            steps.append(session.begin_render(drain=session.source.finished))
        # Every performer's new frame through the blender's render, the low-pass and the
        # foot lock, each one vectorised pass for all.
        new = [(session, step) for session, step in zip(self.sessions, steps) if isinstance(step, PendingFrame)]
        settle_frames([session for session, _ in new], [step for _, step in new])
        shown = []  # (session, its sinks, its frame) of every performer with a frame this tick
        for session, sinks, step in zip(self.sessions, self.sinks, steps):
            frame = session.finish_render(step) if isinstance(step, PendingFrame) else step
            if frame is not None:
                shown.append((session, sinks, frame))
        emit_frames([sinks for _, sinks, _ in shown], [frame for _, _, frame in shown], vmc_time)
        sent = self.clock.now()
        for session, _, frame in shown:
            if session.new_frame:
                session.latency.add(sent - frame.arrival)
        self.ticks += 1
        if not self.clock.virtual and self.ticks % PLAN_EVERY_TICKS == 0:
            self._plan_slack()
        if self.clock.now() >= self._next_status:
            self._next_status += self.config.status_interval
            if self.log_status:
                for line in self.status_lines():
                    log.info(line)

    # -- control ------------------------------------------------------------------------
    def _take_stream_settings(self, model) -> None:
        """The model's own start and correction low-pass (``words.stream_settings_of``), read by
        each stream at its first frame: a running stream keeps its own."""
        for name, value in stream_settings_of(model).items():
            setattr(self.settings, name, value)

    def _apply_control(self) -> None:
        with self._model_lock:
            model, self._pending_model = self._pending_model, None
        if model is not None:
            if not hasattr(model, "with_mix"):  # a model without style codes: mixes mean nothing to it
                for s in self.sessions:
                    s.set_style(None)
            self.worker.set_restyler(model)
            self._take_stream_settings(model)  # for the streams that start from now on
            self.style = style_label(model)
            self._follow_style(self.sessions)
            log.info("model %s is live", self.style)
        if self.remote is not None:
            self._serve_remote()
        if self.control is None:
            return
        self._status_replies = 0
        for command, value, performer, addr in self.control.drain():
            try:
                self.apply(command, value, performer, addr)
            except UserError as exc:
                self._control_error(str(exc))

    def _serve_remote(self) -> None:
        """A worker process: apply what the parent forwards, answer its status requests."""
        try:
            while self.remote.poll():
                kind, *args = self.remote.recv()
                if kind == "status":
                    self.remote.send(("status", self.snapshot()))
                elif kind == "apply":
                    try:
                        self.apply(*args)
                    except UserError as exc:
                        self._control_error(str(exc))
                elif kind == "stop":
                    self.remote_stopped = True
        except (EOFError, OSError):  # the parent is gone: stop cleanly
            self.remote_stopped = True

    def apply(self, command: str, value, performer: str | None = None, reply_to=None) -> None:
        """Apply one setting live (also the API tests and embedders use); the commands
        and what they do are the one table in ``commands.py``."""
        apply_command(self, command, value, performer, reply_to)

    def reply_status(self, addr) -> None:
        if self.control is not None and addr is not None and self._status_replies < STATUS_REPLIES_PER_TICK:
            self._status_replies += 1
            self.control.reply(addr, status_messages(self.snapshot()))

    def set_direction(self, direction: str) -> None:
        model = with_direction(self.worker.restyler, direction)
        self.worker.set_restyler(model)
        self.style = style_label(model)
        self._follow_style(self.sessions)

    def set_style(self, pairs, sessions) -> None:
        """/stylecast/style and /stylecast/mix: crossfade ``sessions`` to the mix of
        (name, weight) ``pairs``, checked against the live model's styles."""
        model = self.worker.restyler
        weights, label = style_mix(model, pairs)
        for s in sessions:
            s.set_style(weights, label, own=model.weights)
        self._follow_style(sessions)

    def _follow_style(self, sessions) -> None:
        """The pace each of ``sessions`` covers ground at, how quickly its hips follow the
        restyled legs, how much of its stance it keeps standing and how far its arms swing
        and hips bob, after a new model, direction
        or style (``--pace``; ``footlock.Pace``, ``PelvisHeight`` and ``GaitAmplitude`` move to
        them smoothly)."""
        model = self.worker.restyler
        for s in sessions:
            s.feet.pace.set_points(pace_of(model, self.config.pace, s.style_target))
            s.feet.pelvis.set_quick_share(quick_hips_of(model, s.style_target))
            s.feet.stance.set_standing(stance_standing_of(model, s.style_target))
            s.feet.amplitude.set_points(**amplitudes_of(model, s.style_target))

    def _control_error(self, message: str) -> None:
        # Counted always, logged rarely: a sender repeating a bad command, or a flood of
        # them, must not become a log line per packet (hardening, issue 7).
        self.control_errors += 1
        n = self.control_errors
        if n <= CONTROL_ERRORS_LOGGED:
            log.warning("control: %s", message)
        elif n % 1000 == 0:
            log.warning("control: %s (%d refused commands so far; not all are logged)", message, n)

    def load_model_async(self, name: str) -> None:
        # One loader thread at a time; requests arriving while it works are coalesced into
        # the latest (hardening: a flood of /stylecast/model used to start one thread per
        # packet, each reading a checkpoint).
        with self._model_lock:
            if self._loader_busy:
                if self._requested_model is not None:
                    self.model_requests_replaced += 1
                self._requested_model = name
                return
            self._loader_busy = True
        threading.Thread(target=self._load_models, args=(name,), name="stylecast-model-loader",
                         daemon=True).start()

    def _load_models(self, name: str | None) -> None:
        while name is not None:
            try:
                model = with_performer_style(self.model_loader(name), self.config.performer_style)
                warm_up(model)  # here, not in its first live call (``Restyler.warm_up``)
            except Exception as exc:  # a bad name or checkpoint must not stop the show
                self._control_error(f"model {name!r} not loaded: {exc}")
            else:
                with self._model_lock:
                    self._pending_model = model
            with self._model_lock:
                name, self._requested_model = self._requested_model, None
                if name is None:
                    self._loader_busy = False

    # -- status -------------------------------------------------------------------------
    def snapshot(self) -> dict:
        performers = [s.counters() for s in self.sessions]
        return {"daemon": {"style": self.style, "model": model_name(self.worker.restyler),
                           "performers": len(self.sessions), "ticks": self.ticks,
                           "hop": self.settings.hop, "delay": self.settings.delay,
                           "model_ready_max_ms": round(self.worker.planner.estimate_ms(), 2),
                           "dropped_ticks": self.dropped_ticks, "faults": self.worker.faults,
                           "control_refused": self.control.refused if self.control else 0},
                "performers": performers}

    def status_lines(self) -> list[str]:
        snap = self.snapshot()
        return [status_line(p, p.get("style") or snap["daemon"]["style"]) for p in snap["performers"]]

    def close(self) -> None:
        """Stop threads, close sockets, finish recordings (valid BVH). Safe to call twice."""
        if self._froze_heap:
            gc.unfreeze()  # whatever the show left behind can be collected again
            self._froze_heap = False
        self.worker.close()
        if self.control is not None:
            self.control.close()
        for sinks in self.sinks:
            sinks.close()
        for s in self.sessions:
            s.source.close()
