"""Every word on time (issue 12): latency presets, the delay chosen from the model's
measured time, one status line when the model is too slow, late words still counted.

These run the real output clock for a few seconds (the point is real timing); they
check behaviour (delays, counters, lines), never speed."""

from __future__ import annotations

import logging
import time

import pytest

from stylecast.motion.clock import RealClock
from stylecast.daemon.config import DaemonConfig, build_config
from stylecast.daemon.engine import Daemon
from stylecast.daemon.latency import LATENCY_PRESETS, SlackPlanner, slack_for
from stylecast.daemon.restylers import IdentityRestyler, StandInRestyler
from stylecast.drivers.bvh.bvh_replay import ReplaySource
from stylecast.motion.errors import UserError

from .test_daemon import walk_clip


class SleepyRestyler:
    """The stand-in restyler, ``seconds`` slower per call from call ``slow_from`` on."""

    def __init__(self, seconds: float, slow_from: int = 1):
        self.seconds, self.slow_from, self.calls = seconds, slow_from, 0
        self.inner = StandInRestyler()

    def restyle_words(self, words):
        self.calls += 1
        if self.calls >= self.slow_from:
            time.sleep(self.seconds)
        return self.inner.restyle_words(words)


def run_real(restyler, seconds: float, **config) -> Daemon:
    cfg = DaemonConfig(control="off", status_interval=3600.0, **config)
    daemon = Daemon(cfg, [ReplaySource(walk_clip(600), "p0", loop=True)], restyler, RealClock(), log_status=False)
    try:
        daemon.run(duration=seconds)
    finally:
        daemon.close()
    return daemon


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
    with caplog.at_level(logging.WARNING, logger="stylecast.daemon"):
        daemon = run_real(IdentityRestyler(), 2.0)
    s = daemon.sessions[0]
    assert daemon.settings.delay == 5 and s.settings.delay == 5
    assert daemon.delay_notes == [] and "too slow" not in caplog.text
    assert s.words > 10 and s.blender.late_frames == 0 and s.words_failed == 0


def test_a_model_too_slow_for_the_hop_gets_a_larger_delay_one_line_and_no_late_words(caplog):
    # 45 ms per call against the default preset's 33 ms of slack (hop 4, delay 5).
    with caplog.at_level(logging.WARNING, logger="stylecast.daemon"):
        daemon = run_real(SleepyRestyler(0.045), 3.0)
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
    restyler = SleepyRestyler(0.045, slow_from=4)
    late_at_raise = []
    cfg = DaemonConfig(control="off", status_interval=3600.0, latency="low")
    daemon = Daemon(cfg, [ReplaySource(walk_clip(600), "p0", loop=True)], restyler, RealClock(), log_status=False)
    raise_slack = daemon._raise_slack

    def spy(needed, reason):
        before = len(daemon.delay_notes)
        raise_slack(needed, reason)
        if len(daemon.delay_notes) > before:
            late_at_raise.append(daemon.sessions[0].blender.late_frames)

    daemon._raise_slack = spy
    try:
        daemon.run(duration=5.0)
    finally:
        daemon.close()
    s = daemon.sessions[0]
    assert daemon.delay_notes and "results ready" in daemon.delay_notes[0]
    assert late_at_raise[0] > 0  # late before the planner knew: counted, not hidden
    assert s.blender.late_frames <= late_at_raise[-1] + 2 * s.settings.hop  # on time after the last raise
