"""Sources by URL: parsing, refusals in one sentence, BVH replay pacing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stylecast.drivers.bvh.bvh_replay import ReplaySource
from stylecast.drivers.sources import open_source
from stylecast.drivers.urls import parse_url
from stylecast.motion.errors import UserError
from stylecast.motion.humanoid import HUMANOID_BONES

from .test_daemon import walk_clip

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "bandai"
WALK = DATA / "dataset-2" / "data" / "dataset-2_walk_normal_001.bvh.gz"


def test_urls_parse_paths_hosts_and_options():
    u = parse_url("bvh:///clips/walk.bvh?loop=1&speed=0.5")
    assert (u.scheme, u.path, u.options) == ("bvh", "/clips/walk.bvh", {"loop": "1", "speed": "0.5"})
    assert u.take({"loop": (bool, False), "speed": (float, 1.0)}) == {"loop": True, "speed": 0.5}
    assert parse_url("bvh://clips/walk.bvh").path == "clips/walk.bvh"
    assert parse_url("walk.bvh.gz").scheme == "bvh"
    v = parse_url("vmc://127.0.0.1:39540")
    assert v.address() == ("127.0.0.1", 39540)


@pytest.mark.parametrize("url, words", [
    ("foo://x", "unknown source scheme"),
    ("bvh:///x.bvh?lop=1", "unknown option lop"),
    ("bvh:///x.bvh?loop=maybe", "must be 0 or 1"),
    ("bvh:///x.bvh?speed=fast", "must be a number"),
    ("bvh:///x.bvh?loop=1&loop=0", "given twice"),
    ("vmc://127.0.0.1:99999", "port"),
    ("just-a-name", "not an endpoint URL"),
])
def test_bad_urls_are_refused_with_one_sentence(url, words):
    with pytest.raises(UserError, match=words) as info:
        open_source(url, "p0")
    message = str(info.value)
    assert "\n" not in message and message.count(". ") == 0


def test_replay_is_paced_by_the_clock_it_is_given():
    clip = walk_clip(30)
    src = ReplaySource(clip, "p0")
    src.start(10.0)
    assert len(src.poll(10.0)) == 1  # frame 0 is due at the start
    assert [f.timestamp for f in src.poll(10.05)] == pytest.approx([10 + i / 60 for i in (1, 2, 3)])
    assert len(src.poll(100.0)) == 26 and src.finished
    looping = ReplaySource(clip, "p0", loop=True)
    looping.start(0.0)
    frames = looping.poll(1.0)
    assert len(frames) == 61 and not looping.finished
    np.testing.assert_array_equal(frames[30].rotations, clip.rotations[0])  # wrapped around


def test_replay_speed_changes_the_timeline_not_the_frames():
    clip = walk_clip(121)
    fast = ReplaySource(clip, "p0", speed=2.0)
    assert fast.num_frames == 121  # the replay never resamples: the session does
    fast.start(0.0)
    frames = fast.poll(0.5)  # half a second at speed 2 is a second of the clip's timeline
    assert len(frames) == int(clip.fps) + 1
    assert np.diff([f.timestamp for f in frames]) == pytest.approx(1 / (2 * clip.fps))
    np.testing.assert_array_equal(frames[20].rotations, clip.rotations[20])
    with pytest.raises(UserError, match="speed"):
        ReplaySource(clip, "p0", speed=0.0)


@pytest.mark.skipif(not WALK.exists(), reason="shared Bandai data not present")
def test_a_bandai_clip_replays_as_a_humanoid_stream_at_its_own_rate():
    pytest.importorskip("stylecast.motion.bvh")
    src = open_source(f"bvh://{WALK}?loop=1&name=alice", "p0")
    assert src.performer == "alice" and src.skeleton.names == HUMANOID_BONES and src.loop
    assert src.num_frames == 273  # at the clip's own 30 fps: the session resamples to 60
    src.start(0.0)
    assert [f.timestamp for f in src.poll(0.1)] == pytest.approx([0.0, 1 / 30, 2 / 30, 3 / 30])
    src.start(0.0)
    frame = src.poll(0.0)[0]
    assert frame.rotations.shape == (len(HUMANOID_BONES), 4) and 50 < frame.root_position[1] < 150


def test_missing_live_drivers_are_refused_clearly(monkeypatch):
    from stylecast.drivers import sources

    monkeypatch.setitem(sources.SOURCE_SCHEMES, "vmc", ("stylecast.drivers.no_such_module", "open_source"))
    with pytest.raises(UserError, match="not available in this install"):
        open_source("vmc://127.0.0.1:39540", "p0")
