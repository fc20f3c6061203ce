"""Batched inference off the I/O path.

The output loop hands over, once per tick, every word that tick completed across all
performers (``submit``); a worker thread runs them through ONE ``restyle_words`` call
and queues the results; the loop picks up whatever has finished (``collect``) at the
start of its next tick and never waits for the model (except under a virtual clock,
where model time is free by definition and waiting is what makes replays exact).
If the worker has fallen behind, the jobs waiting for it are merged into one bigger
batch: catching up costs one call, not several.

A restyler is any object with ``restyle_words(words (B, 60, J, 4)) -> same shape``; each
word reaches it in one hemisphere over time, made so here for the whole batch (a trained
model does that, its call and the checks in one traced call: ``restyle_stream_words``).
An item may carry a fourth element, a style mix (S,) for that word (None: the model's
own); a batch with any mix in it is ONE call ``restyle_words(words, weights (B, S))``
of a multi-style model, whatever mix each performer uses.
A call that raises, returns the wrong shape, or returns non-finite or zero-length
quaternions is a *fault*: the affected words are simply never delivered, so the seam
blender treats them as late and fades that stretch to pass-through; the fault is
counted, the worker carries on.

Every job carries the scheduled time of the tick that submitted it; when its results
are ready the worker records how long after that tick they came (``planner``: model
call, queueing and CPU contention together), which is what the engine's delay must cover
(``daemon.latency``).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque

import numpy as np

from stylecast.motion import rotations as rot

from .latency import SlackPlanner

log = logging.getLogger("stylecast.daemon")
# Jobs (one per tick that completed words) waiting for a busy model. A slow or hung model
# must not make this queue, and the merged catch-up batch behind it, grow without bound:
# past this many, the oldest job's words can no longer be shown in time and are given up
# as failed (the blender shows pass-through for them), counted in ``stale_words``.
MAX_QUEUED_JOBS = 16


class InferenceWorker:
    def __init__(self, restyler, clock=time.monotonic):
        self._restyler = restyler
        self._clock = clock  # the engine's clock: ready times are compared with its ticks
        self.planner = SlackPlanner()
        self._jobs: deque = deque()  # lists of (session index, end, word)
        self._job_ticks: deque = deque()  # the scheduled tick time of each job, in step
        self._results: deque = deque()  # (session index, end, restyled word)
        self._failed: deque = deque()  # (session index, end) of words lost to a fault
        self._cond = threading.Condition()
        self._pending = 0  # jobs submitted and not finished
        self._closing = False
        self.batches = 0
        self.words = 0
        self.faults = 0
        self.fault_words = 0
        self.stale_words = 0  # words given up unprocessed because the model fell behind
        self.last_fault = ""
        self.busy_seconds = 0.0
        self.call_ms = deque(maxlen=600)
        self._thread = threading.Thread(target=self._run, name="stylecast-inference", daemon=True)
        self._thread.start()

    @property
    def restyler(self):
        return self._restyler

    def set_restyler(self, restyler) -> None:
        """Swap the model; jobs already running finish with the old one."""
        self._restyler = restyler

    def submit(self, items: list[tuple[int, int, np.ndarray]], tick_time: float | None = None) -> None:
        """Queue one tick's words; ``tick_time``: that tick's scheduled time (default now)."""
        if not items:
            return
        with self._cond:
            self._jobs.append(items)
            self._job_ticks.append(self._clock() if tick_time is None else tick_time)
            self._pending += 1
            while len(self._jobs) > MAX_QUEUED_JOBS:  # hardening: see MAX_QUEUED_JOBS
                stale = self._jobs.popleft()
                self._job_ticks.popleft()
                self._pending -= 1
                self.stale_words += len(stale)
                self._failed.extend((s, end) for s, end, *_ in stale)
            self._cond.notify_all()

    def collect(self) -> tuple[list, list]:
        """(finished results, failed (session, end) pairs) since the last call."""
        done, failed = [], []
        while self._results:
            done.append(self._results.popleft())
        while self._failed:
            failed.append(self._failed.popleft())
        return done, failed

    def wait_idle(self, timeout: float | None = None) -> bool:
        with self._cond:
            return self._cond.wait_for(lambda: self._pending == 0, timeout)

    def close(self) -> None:
        with self._cond:
            self._closing = True
            self._cond.notify_all()
        self._thread.join(timeout=5.0)

    def _run(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._jobs or self._closing)
                if self._closing:
                    return
                items, ticks = [], []
                while self._jobs:
                    items += self._jobs.popleft()
                    ticks.append(self._job_ticks.popleft())
                merged = len(ticks)
            try:
                self._process(items)
                done = self._clock()
                for tick in ticks:
                    self.planner.add(done - tick)
            finally:
                with self._cond:
                    self._pending -= merged
                    self._cond.notify_all()

    @staticmethod
    def _call(restyler, items: list, words: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Words in any hemisphere -> (restyled words, each continuous in time; (B,) usable),
        the seam blender's input (results are added ``continuous``): the words made
        continuous in time, restyled, checked and the output made continuous, for the
        whole batch here rather than per word in the output loop. A model that can
        (``restyle_stream_words``) does all of it in one call."""
        mixes = [item[3] if len(item) > 3 else None for item in items]
        # A multi-style model's own mix for rows that chose none; nothing for an all-None batch.
        args = () if all(m is None for m in mixes) else \
            (np.stack([restyler.weights if m is None else m for m in mixes]),)
        in_one_call = getattr(restyler, "restyle_stream_words", None)
        if in_one_call is not None:
            out, ok = in_one_call(words, *args)
        else:
            out, ok = restyler.restyle_words(rot.canonical_hemisphere(words, axis=1), *args), None
        out = np.asarray(out, dtype=np.float64)
        if out.shape != words.shape:
            raise ValueError(f"restyler returned shape {out.shape} for words of shape {words.shape}")
        if ok is None:
            return rot.canonical_hemisphere(out, axis=1), rot.usable_words(out)
        return out, np.asarray(ok, dtype=bool)

    def _process(self, items: list) -> None:
        words = np.stack([item[2] for item in items])
        restyler = self._restyler
        t0 = time.perf_counter()
        try:
            out, ok = self._call(restyler, items, words)
        except Exception as exc:  # any model failure is a counted fault, never a crash
            out, ok = None, np.zeros(len(items), bool)
            self.last_fault = f"{type(exc).__name__}: {exc}"
        elapsed = time.perf_counter() - t0
        self.busy_seconds += elapsed
        self.call_ms.append(elapsed * 1e3)
        self.batches += 1
        self.words += len(items)
        if not ok.all():
            self.faults += 1
            self.fault_words += int((~ok).sum())
            if out is not None:
                self.last_fault = "restyler returned non-finite or zero quaternions"
            if self.faults in (1, 10, 100) or self.faults % 1000 == 0:
                log.warning("restyler fault #%d (%s): %d word(s) fall back to pass-through",
                            self.faults, self.last_fault, int((~ok).sum()))
        for (s, end, *_), good, i in zip(items, ok, range(len(items))):
            if good:
                self._results.append((s, end, out[i]))
            else:
                self._failed.append((s, end))
