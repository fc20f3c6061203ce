"""Floods (issue 7, part 2), the CI version of bench/flood.py: a few seconds of junk on
loopback at whatever rate this machine sustains (20,000/s asked) beside legitimate
performers, through a live daemon on the real clock.

What is asserted does not depend on the machine's speed: on a loaded box the output
clock may drop ticks by design (counted), so the legitimate streams are checked for
*unaccounted* loss: every output frame the daemon sent arrived; every missing output
tick is one the daemon dropped and counted; every frame a live performer sent was read.
The junk goes to its own ``vmc://`` input port and to the control port; each junk
datagram is rejected with exactly one reason, so "counted by reason == read" is exact,
and the kernel's drops (a full receive buffer, before the daemon could read them) are
reported beside it. The log stays short: junk is counted, never logged line by line.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
RATE = float(os.environ.get("STYLECAST_FLOOD_RATE", "20000"))


def load_flood():
    spec = importlib.util.spec_from_file_location("stylecast_bench_flood", REPO / "bench" / "flood.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs Linux /proc for the memory figures")
def test_short_flood_beside_legitimate_performers():
    flood = load_flood()
    r = flood.run_flood(seconds=3.0, rate=RATE, performers=1, replays=2, junk_to="separate", junk_senders=1,
                        quiet=True)
    flood.print_report(r)
    assert r["alive"]
    by_kind = {}
    for p in r["performers"]:
        by_kind.setdefault(p["kind"], []).append(p)
    # Replayed performers: every frame sent reached the receiver; every gap in the frame
    # indices is a counted skip, and every skip answers a tick the daemon dropped or a tick
    # it held because the source was late (both counted). A replay's own thread can be late
    # on a loaded two-core machine under the flood (one held tick, then one more skip than
    # dropped ticks, in one CI run of 2026-11-28): that depends on the machine, so it is
    # accounted for here, not forbidden; a frozen performer still fails the count above.
    for p in by_kind["replay"]:
        assert p["out_sent"] > 100 and p["out_received"] == p["out_sent"], p
        assert p["out_missing_ticks"] <= r["dropped_ticks"], p
        assert p["index_gaps"] == p["skipped"] <= p["dropped"] + p["held"], p
    # The live VMC performer: every frame it sent was read, none refused.
    (live,) = by_kind["live"]
    assert live["legit_sent"] > 100 and live["legit_read"] == live["legit_sent"], live
    assert live["junk_counted"] == 0 and live["out_received"] == live["out_sent"], live
    # The junk: every datagram the daemon read was counted under one reason.
    (junk,) = by_kind["junk"]
    assert junk["datagrams_read"] > 1000 and junk["junk_counted"] == junk["datagrams_read"], junk
    assert junk["junk_sent"] >= junk["datagrams_read"]
    c = r["control"]
    assert c["read"] > 100 and c["counted"] == c["read"] and c["sent"] >= c["read"], c
    # Bounded memory and a short log.
    assert r["peak_rss_mb"] - r["rss_before_mb"] < 150, r
    assert sum(r["log_records"].values()) < 20, r["log_samples"]
