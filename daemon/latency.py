"""Latency presets and the delay that keeps every word on time.

A word cut on tick k is first needed on tick k + s, with s = delay - hop + 1 (the model's
*slack* in frame periods; see ``motion.words``). Whether s is enough depends on the
model, the device, the batch and the machine's load, so the daemon does not guess:

* before the clock starts it times the model on a batch as large as one tick will carry
  (``calibrate``) and starts with a slack that covers it;
* while it runs, the inference worker records for every job how long after its tick's
  scheduled time the result was ready (model call, queueing and contention for the
  CPU together), and ``SlackPlanner`` raises the delay to the smallest safe one when the
  slowest of the recent jobs no longer fits, with ONE status line saying why;
* and once the load that forced a raise has passed (the slowest recent job would fit
  one frame less with ``LOWER_MARGIN_FACTOR``'s headroom, for ``LOWER_AFTER_CHECKS``
  checks in a row) it lowers the delay again, one frame every ``LOWER_EVERY_CHECKS``
  checks while that lasts and never below the configured one, so a burst of load does
  not cost latency for the rest of the show. Each session works the frame off by
  skipping one input frame (counted, as for any lag; see daemon.session).

Words that were late before a raise stay counted.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from stylecast.motion.clock import OUTPUT_FPS as FPS  # the one definition of the frame rate
from stylecast.motion.words import DEFAULT_HOP

PERIOD = 1.0 / FPS
MARGIN_FACTOR = 1.25  # headroom over the measured time: load changes, batches grow
MARGIN_S = 0.002  # and a fixed 2 ms for the tick's own work before the collect
CALIBRATION_FACTOR = 2.0  # startup timing runs alone; live, the output loop competes for the CPU
MIN_SAMPLES = 30  # jobs measured before the live estimate is trusted (a one-off stall is not a trend)
WINDOW = 600  # jobs the live estimate looks back over (10 s at one job per tick)
MAX_SLACK = 60  # ticks (1 s): past this the model is hopeless for live use; said so, not chased
# Lowering is slow and asks for more headroom than staying does: a delay that went down on
# a lull and up on the next burst would hitch the output each time. The lowered delay must
# cover the slowest recent job with twice the raise's relative headroom (50 % against
# 25 %), so between a raise (at the default's slack of 2 frames: a result later than
# 25.1 ms) and a lowering back into it (every result within 20.9 ms) lies a 4 ms band.
# Until 2026-11-27 it asked for two whole frames spare (results within 11.7 ms), which a
# 16-performer soak never saw again after a one-off 25 ms result at minute 23: that raise
# cost 17 ms of latency for the rest of the hour.
LOWER_MARGIN_FACTOR = 2 * MARGIN_FACTOR - 1
LOWER_AFTER_CHECKS = 30  # consecutive planner checks (one a second: 30 s) with that much headroom
# Once calm is established, each further frame comes off after this many more calm checks:
# at one frame per 30 s, a delay raised to 34 frames by a 400 ms stall in the soak would
# take 13 minutes to come back. Each lowering costs one skipped input frame (the session's
# own lag rule), so they are kept a few seconds apart.
LOWER_EVERY_CHECKS = 3


@dataclass(frozen=True)
class LatencyPreset:
    hop: int  # frames between words
    slack: int  # frame periods the model gets per word at the start (delay = hop + slack - 1)
    about: str


# --latency NAME. "default": <= 100 ms p99 added latency (83 ms of delay); "low": <= 35 ms
# (one frame of delay, a word every frame); "relaxed": the pre-issue-12 default, for slow
# machines and many performers.
LATENCY_PRESETS = {
    "default": LatencyPreset(hop=DEFAULT_HOP, slack=2, about=f"hop {DEFAULT_HOP}, delay {DEFAULT_HOP + 1} frames "
                                                              f"({(DEFAULT_HOP + 1) / FPS * 1e3:.0f} ms)"),
    "low": LatencyPreset(hop=1, slack=1, about="hop 1, delay 1 frame (17 ms)"),
    "relaxed": LatencyPreset(hop=15, slack=1, about="hop 15, delay 15 frames (250 ms)"),
}


def slack_for(seconds: float, factor: float = MARGIN_FACTOR) -> int:
    """Frame periods a word needs when its result is ready ``seconds`` after its tick."""
    return max(1, math.ceil((seconds * factor + MARGIN_S) / PERIOD - 1e-9))


def calibrate(restyler, batch: int, joints: int = 22, repeats: int = 3) -> float:
    """Seconds one model call on ``batch`` words takes (median after a warm-up call)."""
    import time

    import numpy as np

    words = np.zeros((max(1, batch), 60, joints, 4))
    words[..., 3] = 1.0
    restyler.restyle_words(words)  # warm-up: first calls allocate, load kernels, fill caches
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        restyler.restyle_words(words)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


class SlackPlanner:
    """Watches when results become ready and says when the delay must grow."""

    def __init__(self):
        self.ready_after: deque = deque(maxlen=WINDOW)  # seconds after the submitting tick
        self.calm_checks = 0  # consecutive checks that found room to lower (``can_lower``)

    def add(self, seconds: float) -> None:
        self.ready_after.append(seconds)

    def needed_slack(self, factor: float = MARGIN_FACTOR) -> int | None:
        """The smallest safe slack by the slowest recent job (with ``factor``'s headroom),
        or None while too few are known. The slowest, not a percentile: every word on time
        means the tail too (a 95th percentile, the first choice, let 0.2 % of frames come
        late in a 16-performer soak while the delay never moved; the lowering undoes what a
        one-off stall costs)."""
        if len(self.ready_after) < MIN_SAMPLES:
            return None
        return slack_for(max(self.ready_after), factor)

    def can_lower(self, slack: int, floor: int) -> bool:
        """Called once per check: may the slack come down one frame (not below ``floor``)?
        Only after ``LOWER_AFTER_CHECKS`` checks in a row found the slowest recent job
        fitting one frame less with ``LOWER_MARGIN_FACTOR``'s headroom, then every
        ``LOWER_EVERY_CHECKS`` while that lasts; a busier check (or a raise) starts the
        count again from zero."""
        needed = self.needed_slack(LOWER_MARGIN_FACTOR)
        if needed is None or slack <= floor or needed > slack - 1:
            self.calm_checks = 0
            return False
        self.calm_checks += 1
        if self.calm_checks < LOWER_AFTER_CHECKS:
            return False
        self.calm_checks = LOWER_AFTER_CHECKS - LOWER_EVERY_CHECKS
        return True

    def estimate_ms(self) -> float:
        """The slowest recent job, ms after its tick (0 before any)."""
        return max(self.ready_after, default=0.0) * 1e3


def delay_line(reason: str, hop: int, old: int, new: int, capped: bool) -> str:
    """The one status line for a raised delay."""
    cap = (f"; capped at {new} frames, so some words will still be late: use a faster --device, a larger "
           f"--hop or fewer performers" if capped else "")
    return (f"model too slow for hop {hop} with delay {old} ({reason}); delay raised to {new} frames "
            f"({new * 1000 / FPS:.0f} ms added latency) so every word is on time{cap}")


def lowered_line(reason: str, old: int, new: int) -> str:
    """The one status line for a delay lowered again after the load has passed."""
    return (f"model has time to spare ({reason}); delay lowered from {old} to {new} frames "
            f"({new * 1000 / FPS:.0f} ms added latency), one input frame skipped to catch up")
