"""Every word on time (issue 12): latency presets, the delay chosen from the model's
measured time, one status line when the model is too slow, late words still counted.

These run the real output clock for a few seconds (the point is real timing); they
check behaviour (delays, counters, lines), never speed."""

from __future__ import annotations

import logging
import threading
import time

import pytest

from stylecast.motion.clock import RealClock
from stylecast.daemon.config import DaemonConfig, build_config
from stylecast.daemon.engine import Daemon
from stylecast.daemon import latency
from stylecast.daemon.latency import (LATENCY_PRESETS, LOWER_AFTER_CHECKS, LOWER_EVERY_CHECKS, SlackPlanner,
                                       slack_for)
from stylecast.daemon.restylers import IdentityRestyler, StandInRestyler
from stylecast.drivers.bvh.bvh_replay import ReplaySource
from stylecast.motion.errors import UserError

from .test_daemon import walk_clip


class SleepyRestyler:
    """The stand-in restyler, ``seconds`` slower per call from call ``slow_from`` on (and
    before call ``slow_until``, if given)."""

    def __init__(self, seconds: float, slow_from: int = 1, slow_until: int | None = None):
        self.seconds, self.slow_from, self.slow_until, self.calls = seconds, slow_from, slow_until, 0
        self.inner = StandInRestyler()

    def restyle_words(self, words):
        self.calls += 1
        if self.calls >= self.slow_from and (self.slow_until is None or self.calls < self.slow_until):
            time.sleep(self.seconds)
        return self.inner.restyle_words(words)


def run_real(restyler, seconds: float, until=None, **config) -> tuple[Daemon, list[tuple[int, int]]]:
    """One looping performer on the real clock for ``seconds``, or until ``until(daemon,
    changes)`` holds after a planner check. Also returns the delay's history: (delay, late
    frames so far) at the start and after each planner check that changed it."""
    cfg = DaemonConfig(control="off", status_interval=3600.0, **config)
    daemon = Daemon(cfg, [ReplaySource(walk_clip(600), "p0", loop=True)], restyler, RealClock(), log_status=False)
    if hasattr(restyler, "daemon"):
        restyler.daemon = daemon  # a stand-in that times its results on the daemon's tick grid
    changes = [(daemon.settings.delay, 0)]
    plan = daemon._plan_slack
    stop = threading.Event()

    def watched():
        plan()
        if daemon.settings.delay != changes[-1][0]:
            changes.append((daemon.settings.delay, daemon.sessions[0].blender.late_frames))
        if until is not None and until(daemon, changes):
            stop.set()

    daemon._plan_slack = watched
    try:
        daemon.run(stop=stop, duration=seconds)
    finally:
        daemon.close()
    return daemon, changes


def assert_late_only_where_the_delay_rose(changes, late_frames: int) -> None:
    """Late frames may appear only in a stretch the planner answered by raising the delay:
    the slow spell itself, or a shared machine's own stall (CI, 2026-12-07: 50 -> 52 late
    while at 6, then raised to 7). None after a lowering left alone, and none after the last
    change, the lowering back to the preset's."""
    for (before, late_before), (after, late_after) in zip(changes, changes[1:]):
        assert late_after == late_before or after > before, changes
    assert late_frames == changes[-1][1], changes


def test_late_frames_are_allowed_only_where_the_planner_raised_the_delay():
    """The real-clock tests' check on a delay's history: CI's stall (2 late at delay 6, then
    raised to 7) passes; a lowering followed by late frames, or late frames after the last
    change, fails."""
    assert_late_only_where_the_delay_rose([(5, 0), (8, 50), (7, 50), (6, 50), (7, 52), (6, 52), (5, 52)], 52)
    with pytest.raises(AssertionError):
        assert_late_only_where_the_delay_rose([(5, 0), (8, 50), (7, 52), (6, 52), (5, 52)], 52)
    with pytest.raises(AssertionError):
        assert_late_only_where_the_delay_rose([(5, 0), (8, 50), (5, 50)], 51)

def test_presets_set_hop_and_delay_and_flags_override_them():
    cfg = build_config({}, {})
    assert (cfg.latency, cfg.hop, cfg.delay) == ("default", 4, 5)
    assert cfg.delay * 1000 / 60 <= 100 - 10  # the default's added latency, with room for the tick's work
    low = build_config({}, {"latency": "low"})
    assert (low.hop, low.delay) == (1, 1)
    assert build_config({}, {"latency": "low", "hop": 3}).delay == 0  # an explicit hop: delay = hop
    assert build_config({}, {"hop": 6, "delay": 9}).delay == 9
    with pytest.raises(UserError, match="not a preset; use one of default, low, relaxed"):
        build_config({}, {"latency": "fast"})
    assert set(LATENCY_PRESETS) == {"default", "low", "relaxed"}


def test_slack_covers_the_measured_time_with_margin():
    assert slack_for(0.0) == 1
    assert slack_for(0.010) == 1  # 10 ms * 1.25 + 2 ms < 16.7 ms
    assert slack_for(0.020) == 2
    assert slack_for(0.050) == 4
    planner = SlackPlanner()
    for _ in range(29):
        planner.add(0.050)
    assert planner.needed_slack() is None  # too few jobs to call it a trend
    planner.add(0.050)
    assert planner.needed_slack() == 4


def test_a_fast_model_keeps_the_presets_delay_and_no_word_is_late(caplog):
    # Two tries: a 2 s run on a shared VM can catch a stall of the machine itself (once in
    # a full-suite run the identity model's results came 73 ms late and the delay rose to
    # 7, rightly); a fast model must hold the preset's delay in a run the machine allows.
    for attempt in range(2):
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="stylecast.daemon"):
            daemon, _ = run_real(IdentityRestyler(), 2.0)
        if daemon.settings.delay == 5 or attempt == 1:
            break
    s = daemon.sessions[0]
    assert daemon.settings.delay == 5 and s.settings.delay == 5, daemon.delay_notes
    assert daemon.delay_notes == [] and "too slow" not in caplog.text
    assert s.words > 10 and s.blender.late_frames == 0 and s.words_failed == 0


def test_a_model_too_slow_for_the_hop_gets_a_larger_delay_one_line_and_no_late_words(caplog):
    # 45 ms per call against the default preset's 33 ms of slack (hop 4, delay 5).
    with caplog.at_level(logging.WARNING, logger="stylecast.daemon"):
        daemon, _ = run_real(SleepyRestyler(0.045), 3.0)
    s = daemon.sessions[0]
    assert daemon.settings.delay > 5 and s.settings.delay == daemon.settings.delay
    assert len(daemon.delay_notes) == 1, daemon.delay_notes
    line = daemon.delay_notes[0]
    assert "model too slow for hop 4 with delay 5" in line and f"raised to {daemon.settings.delay} frames" in line
    assert caplog.text.count("model too slow") == 1
    assert s.words > 10 and s.blender.late_frames == 0 and s.words_failed == 0
    assert daemon.snapshot()["daemon"]["delay"] == daemon.settings.delay


def test_a_model_that_slows_down_live_is_caught_by_the_planner_and_late_words_stay_counted():
    # Fast when timed at start (3 calls), then 45 ms per call: words are late until the
    # planner has seen enough jobs, then the delay grows and no further word is late.
    daemon, changes = run_real(SleepyRestyler(0.045, slow_from=4), 5.0, latency="low")
    late_at_raise = [late for _, late in changes[1:]]
    s = daemon.sessions[0]
    assert daemon.delay_notes and "results ready" in daemon.delay_notes[0]
    assert late_at_raise[0] > 0  # late before the planner knew: counted, not hidden
    assert s.blender.late_frames <= late_at_raise[-1] + 2 * s.settings.hop  # on time after the last raise


def test_one_slow_job_in_the_window_sets_the_slack():
    # The tail a 95th percentile would let through (a word late at an unmoved delay): one
    # 50 ms job among 599 fast ones needs the slack the 50 ms job needs.
    planner = SlackPlanner()
    for _ in range(599):
        planner.add(0.005)
    assert planner.needed_slack() == 1
    planner.add(0.050)
    assert planner.needed_slack() == slack_for(0.050) == 4
    assert planner.estimate_ms() == 50.0


def test_the_planner_lowers_only_after_a_run_of_checks_with_room_to_spare():
    planner = SlackPlanner()
    for _ in range(40):
        planner.add(0.005)  # needs a slack of 1
    assert all(not planner.can_lower(slack=3, floor=1) for _ in range(LOWER_AFTER_CHECKS - 1))
    assert planner.can_lower(slack=3, floor=1)  # the 30th calm check in a row
    then = [planner.can_lower(slack=3, floor=1) for _ in range(LOWER_EVERY_CHECKS)]
    assert then == [False] * (LOWER_EVERY_CHECKS - 1) + [True]  # and then every few checks while calm
    for _ in range(LOWER_AFTER_CHECKS + 1):
        assert not planner.can_lower(slack=3, floor=3)  # never below the configured slack
    for _ in range(600):
        planner.add(0.030)  # a busier stretch: needs 3
    assert not planner.can_lower(slack=3, floor=1)  # resets the run, from the start
    for _ in range(600):
        planner.add(0.005)
    assert not any(planner.can_lower(slack=3, floor=1) for _ in range(LOWER_AFTER_CHECKS - 1))


def test_the_planner_lowers_into_a_slack_the_slowest_job_fits_with_more_headroom_than_a_raise_asks():
    # The default's slack is 2 frames (33.3 ms): a raise comes with a result later than
    # 25.1 ms (25 % headroom and 2 ms), a lowering back into it with every recent result
    # within 20.9 ms (50 % and 2 ms), and between the two the delay stays where it is.
    def lowers(seconds: float) -> bool:
        planner = SlackPlanner()
        for _ in range(40):
            planner.add(seconds)
        return any(planner.can_lower(slack=3, floor=2) for _ in range(LOWER_AFTER_CHECKS))

    assert lowers(0.005) and lowers(0.014)  # 14 ms: two whole frames spare it would never have had
    assert lowers(0.0205) and not lowers(0.0215)
    for seconds in (0.0215, 0.024):  # fits the slack of 2 (no raise) but not with a lowering's headroom
        planner = SlackPlanner()
        for _ in range(40):
            planner.add(seconds)
        assert planner.needed_slack() == 2
        assert not any(planner.can_lower(slack=3, floor=2) for _ in range(3 * LOWER_AFTER_CHECKS))


def test_after_a_one_off_stall_the_delay_comes_back_although_every_result_takes_most_of_a_frame(monkeypatch):
    # Every result ready about 16.4 ms after its tick (the stand-in sleeps until 15 ms after
    # it; midway between the 11.7 ms this test needs and the lowering's 20.9 ms), one 46 ms
    # later: the stall makes its words
    # late and raises the delay, and once it has left the window the delay comes back to the
    # preset's, with results that never left two whole frames of slack unused (they need
    # more than 11.7 ms), the rule that kept a soak's one-off raise for the rest of the hour.
    # The results are timed on the daemon's own tick grid, not as a fixed model time: with
    # the tick's work before the call (about 2.7 ms on one VM, up to 11 ms now and then on
    # another) a fixed 9 ms call came back 11.6-12.3 ms after its tick on the first, either
    # side of the 11.7 ms this test needs, and a 10 ms one over the lowering's 20.9 ms on
    # the second.
    monkeypatch.setattr(latency, "WINDOW", 30)
    monkeypatch.setattr(latency, "LOWER_AFTER_CHECKS", 2)
    monkeypatch.setattr(latency, "LOWER_EVERY_CHECKS", 2)

    class StallOnce(SleepyRestyler):
        daemon = None  # set by ``run_real``

        def restyle_words(self, words):
            # The inner stand-in's own time is spent first and counted in the 15 ms. Run
            # after the sleep it came on top: on a slow day the calibration timed a call at
            # 17.8 ms, which doubled is past its two frames, and results strayed over the
            # lowering's 20.9 ms, so the delay stayed at 6 for the test's 90 s (twice in a row).
            self.calls += 1
            now = self.daemon.clock.now()
            if self.daemon.ticks == 0:  # timed before the clock starts (``Daemon._calibrate``)
                ready = now + self.seconds
            else:
                tick = self.daemon.ticks  # the submitting tick: the latest one due by now
                while self.daemon.tick_time(tick) > now:
                    tick -= 1
                ready = self.daemon.tick_time(tick) + self.seconds + (0.046 if self.calls == 40 else 0.0)
            out = self.inner.restyle_words(words)
            time.sleep(max(0.0, ready - self.daemon.clock.now()))
            return out

    def recovered(daemon, changes):
        return max(d for d, _ in changes) > 5 and daemon.settings.delay == 5

    # Up to 90 s: a shared machine's own stalls raise the delay again now and then (it stops
    # as soon as the delay is back, about 10 s on a quiet machine).
    daemon, changes = run_real(StallOnce(0.015), 90.0, until=recovered)
    s = daemon.sessions[0]
    delays = [d for d, _ in changes]
    assert max(delays) > 5, daemon.delay_notes  # the stall raised it
    assert daemon.settings.delay == 5 == s.settings.delay, daemon.delay_notes  # and it came back
    assert slack_for(min(daemon.worker.planner.ready_after)) == 2  # never two frames to spare
    assert_late_only_where_the_delay_rose(changes, s.blender.late_frames)  # the stall's words only


def test_after_a_slow_spell_the_delay_comes_back_down_to_the_presets_without_late_words(monkeypatch):
    # 45 ms a call for calls 4..59 (about 4 s at hop 4), fast after: the planner raises
    # the delay during the spell and lowers it one frame at a time after it, back to the
    # preset's 5 frames; each lowering costs one skipped input frame and no late word.
    monkeypatch.setattr(latency, "WINDOW", 30)  # the estimate forgets the spell in 2 s ...
    monkeypatch.setattr(latency, "LOWER_AFTER_CHECKS", 2)  # ... lowers after 2 calm checks ...
    monkeypatch.setattr(latency, "LOWER_EVERY_CHECKS", 2)  # ... then every 2
    # Until one planner check after the delay is back at the preset's (its skip is taken on
    # the next tick), about 14 s on a quiet machine, at most 45 s: on a loaded one results
    # come back later, and the planner waits longer for its calm.
    back = []

    def recovered(daemon, changes):
        back.append(max(d for d, _ in changes) > 5 and daemon.settings.delay == 5)
        return back[-2:] == [True, True]

    daemon, changes = run_real(SleepyRestyler(0.045, slow_from=4, slow_until=60), 45.0, until=recovered)
    delays = [d for d, _ in changes]
    s = daemon.sessions[0]
    raised = [line for line in daemon.delay_notes if "raised" in line]
    lowered = [line for line in daemon.delay_notes if "lowered" in line]
    top = max(delays)
    assert raised and top > 5, daemon.delay_notes
    assert daemon.settings.delay == 5 == s.settings.delay, daemon.delay_notes  # back to the preset's
    # Down one frame at a time. A shared machine's own stall may raise it again on the way
    # down (CI, 2026-12-07: 9, 8, 7, 6, 7, 6, 5), as in the test above; each lowering is still
    # one frame, and one note.
    steps = [b - a for a, b in zip(delays, delays[1:])]
    assert all(step == -1 for step in steps if step < 0) and delays[-1] == 5, delays
    assert sum(step < 0 for step in steps) >= top - 5, delays
    assert len(lowered) == sum(step < 0 for step in steps), (lowered, delays)
    assert "delay lowered from" in lowered[0] and "frame skipped" in lowered[0]
    assert s.skipped >= len(lowered)
    assert_late_only_where_the_delay_rose(changes, s.blender.late_frames)  # lowering made none late


@pytest.mark.parametrize("name", ["normal2exhausted", "multistyle"])
def test_every_generator_a_model_can_run_live_is_traced_before_it_goes_live(name):
    # A generator's first call traces its graph (130-160 ms alone, 250 ms in a loaded
    # daemon): a model swapped in live once paid it on the clock, its first words late
    # and the delay raised to 23 frames. Both at the start and in the background loader,
    # every direction it may switch to is run once before the clock or the swap.
    from stylecast.daemon.restylers import load_restyler
    from stylecast.models import pipeline

    def generators(model):  # the modules its calls run (pipeline's key)
        if name == "normal2exhausted":
            return [model._network(1, direction)[0] for direction in ("a2b", "b2a")]
        return [model._network(1)[0]]

    cfg = DaemonConfig(control="off", status_interval=3600.0)
    started = load_restyler(name)
    daemon = Daemon(cfg, [ReplaySource(walk_clip(120), "p0")], started, RealClock(), log_status=False)
    try:
        daemon._calibrate()  # what run() does before the clock starts
        def traced(model):  # the graph the model thread runs (``Restyler.restyle_stream_words``)
            return all(pipeline.traced(g, pipeline.StreamWordPipeline) for g in generators(model))

        assert traced(started)
        daemon._load_models(name)  # the background loader's work, here in this thread
        swapped = daemon._pending_model
        assert swapped is not None and swapped is not started
        assert traced(swapped)
    finally:
        daemon.close()
