"""Soak (issue 7, part 6), the CI version: bench/soak.py for one minute (four performers
replaying Bandai walks at 60 fps through the real daemon on the real clock; the hour-long
run is ``python bench/soak.py --minutes 60 --performers 4``).

Asserted, independently of the machine's speed:
* memory: RSS at the end minus RSS after a 20 s warm-up stays under 30 MB, and threads
  and file descriptors do not grow;
* the output clock keeps its schedule: ticks run plus ticks dropped stay within a few
  ticks of 60 x elapsed wall time at every sample (the schedule is t0 + k/60, so drift
  can only come from a bookkeeping bug), and the receiving process, which stamps every
  frame on the system clock, measures no rate drift beyond 1000 ppm;
* every frame the daemon sent arrived.
Dropped ticks (a loaded machine may drop some, by design) and latency are reported.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs Linux /proc for the memory figures")
def test_one_minute_soak_of_four_performers():
    spec = importlib.util.spec_from_file_location("stylecast_bench_soak", REPO / "bench" / "soak.py")
    soak = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(soak)
    r = soak.soak(minutes=1.0, performers=4, sample_every=10.0, restyler="standin")
    s = r["summary"]
    assert s["rss_growth_mb"] < 30, r["samples"]
    assert s["threads_start_end"][0] == s["threads_start_end"][1]
    assert s["fds_start_end"][0] == s["fds_start_end"][1]
    assert s["max_abs_clock_offset_ticks"] <= 3.5, r["samples"]  # MAX_BACKLOG_TICKS + the tick in progress
    assert s["frames_received"] == s["frames_sent"] > 4 * 50 * 60
    for k, v in r["received"].items():
        assert v["missing_ticks"] <= s["dropped_ticks"], (k, v)
        assert abs(v["drift_ppm"]) < 1000, (k, v)
    assert 3590 <= s["ticks"] <= 3601
