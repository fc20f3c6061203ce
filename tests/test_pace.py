"""The style's pace (models/pace.py, motion/footlock/ ``Pace``): the table is what the
training clips measure, and a stream slowed to a style's pace covers ground at that pace
while its planted feet stay planted, its strides shorten without a pop, and nothing moves
where the restyle is not shown."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stylecast.models import data as D
from stylecast.models.metrics import jerk, travel_speed, world_positions
from stylecast.models.pace import PACES, SLOWEST_WALK, measure_paces, pace_points
from stylecast.motion.footlock import FEET, FootLock, Pace, leg_chain
from stylecast.motion.words import planned_mix

DATA = D.default_data_dir()
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason=f"the shared Bandai data is not at {DATA}")


@needs_data
def test_the_pace_table_is_what_the_training_clips_measure():
    measured = measure_paces(D.list_files(DATA))
    assert set(measured) == set(PACES)
    for style, (walks, runs) in measured.items():
        assert PACES[style] == pytest.approx((walks, runs), abs=0.051), style


def test_pace_points_map_the_source_speeds_onto_the_target_mix():
    assert all(a == b for a, b in pace_points("normal", {"normal": 1.0}))  # the same style: the same pace
    slow = pace_points("normal", {"elderly": 1.0})  # the walks at the slowest a walk is made
    assert [b / a for a, b in slow] == pytest.approx([SLOWEST_WALK, 147.2 / 281.4])
    assert [b / a for a, b in pace_points("normal", {"exhausted": 1.0})] == pytest.approx([103.7 / 109.8, 225.7 / 281.4])
    half = pace_points("normal", {"elderly": 0.5, "active": 0.5})
    assert [b for _, b in half] == pytest.approx([(71.3 + 142.4) / 120, (147.2 + 338.8) / 120])
    assert pace_points("normal", {"dancing": 1.0}) == () and pace_points("robot", {"normal": 1.0}) == ()


def test_a_pace_ratio_is_the_line_through_its_points():
    pace = Pace(replace(FEET["input"], pace=((2.0, 1.6), (5.0, 3.5))))
    assert pace.ratio(0.0) == pytest.approx(0.8) and pace.ratio(1.0) == pytest.approx(0.8)
    assert pace.ratio(3.5) == pytest.approx((1.6 + 0.5 * 1.9) / 3.5)
    assert pace.ratio(9.0) == pytest.approx(0.7)  # beyond the last point: its ratio
    assert Pace(FEET["input"]).ratio(3.0) == 1.0  # no points: the input's pace
    faster = Pace(replace(FEET["input"], pace=((2.0, 2.6),)))  # a faster style: a pace only slows
    assert faster.ratio(2.0) == 1.0


def with_the_body(roots: np.ndarray) -> np.ndarray:
    """Both input ankles (n, 2, 3) going along with the root, 10 cm to either side."""
    return roots[:, None] + np.array([[10.0, -90.0, 0.0], [-10.0, -90.0, 0.0]])


def held_out_walk():
    files = [f for f in D.files_for_style(D.list_files(DATA), "normal", "val") if f.action == "walk"]
    m = D.load_motions(files[:1])[0]
    return m.root_positions.astype(np.float64), m.rotations.astype(np.float64)


@needs_data
@pytest.mark.parametrize("feet", ["input", "stance", "path"])
def test_at_a_slower_pace_a_walk_covers_less_ground_with_its_planted_feet_still(feet):
    from stylecast.models.data import bandai_skeleton

    roots, q = held_out_walk()
    sk = bandai_skeleton(D.list_files(DATA))
    ratio = 0.8
    speed = travel_speed(roots)
    settings = replace(FEET[feet], pace=((speed, ratio * speed),))  # 0.8 of the input's speed at any speed
    lock = FootLock(sk, settings=settings)
    contacts = lock.push(roots, q)
    new_roots, out = lock.apply(0, roots, q, q)  # an unchanged pose: the pace alone
    # the body covers 0.8 of the input's ground once the low-passes have settled
    settled = slice(90, None)
    step_in = np.linalg.norm(np.diff(roots[settled][:, [0, 2]], axis=0), axis=1).sum()
    step_out = np.linalg.norm(np.diff(new_roots[settled][:, [0, 2]], axis=0), axis=1).sum()
    assert step_out / step_in == pytest.approx(ratio, abs=0.02)
    # a foot the lock holds fully stays where it landed, as still as the input's own
    p_in, _, _ = leg_chain(roots, q, sk.offsets)
    p_out, _, _ = leg_chain(new_roots, out, sk.offsets)
    w = lock.weights(0, len(q))
    held = (w[1:] >= 1.0) & (w[:-1] >= 1.0)

    def slide(p):  # the slower of ankle and ball, as the contact detector has it (a heel lifts first)
        return np.linalg.norm(np.diff(p[:, :, 2:4][..., [0, 2]], axis=0), axis=-1).min(axis=-1)[held]

    assert held.sum() > 100 and contacts.any()
    # (a foot carried with the body instead slides back by a fifth of the body's step: 0.38 cm a frame)
    assert slide(p_out).mean() <= slide(p_in).mean() + FEET[feet].stance_rate + 1e-3
    # shorter strides, not pops: the largest one-frame jerk stays near the input's own
    j_in, j_out = jerk(world_positions(q, roots, sk)), jerk(world_positions(out, new_roots, sk))
    assert j_out.max() < 1.5 * j_in.max()
    assert j_out.mean() < j_in.mean()  # slower feet


def test_the_pace_follows_the_share_of_the_restyle_shown():
    """Pass-through (mix 0) leaves the travel alone; a fade moves the body's speed smoothly."""
    n = 300
    roots = np.stack([np.zeros(n), np.full(n, 100.0), 2.0 * np.arange(n)], axis=1)  # 2 cm a frame
    settings = replace(FEET["input"], pace=((2.0, 1.5),))
    weights = np.zeros((n, 2))
    ankles = with_the_body(roots)
    body, _ = Pace(settings).track(roots, ankles, weights, np.zeros(n))
    assert np.abs(body).max() == 0.0
    mix = np.clip((np.arange(n) - 100) / 30.0, 0.0, 1.0)  # pass-through, then a 30-frame fade-in
    body, feet = Pace(settings).track(roots, ankles, weights, mix)
    speed = 2.0 - np.diff(body[:, 1])  # the output's step
    assert speed[:100] == pytest.approx(2.0) and speed[-50:] == pytest.approx(1.5, abs=5e-3)
    assert np.abs(np.diff(speed, 2)).max() < 0.01  # no kink
    # free feet going with the body (here never locked) keep up with its shift
    np.testing.assert_allclose(feet[-1], np.tile(body[-1], (2, 1)), atol=0.05)


def test_a_stream_shown_restyled_from_its_first_frame_is_at_its_pace_from_its_first_step():
    """Nothing was shown before a stream: its pace starts settled on its first step (from
    rest, a run started live went at the input's speed for its first half second), frame by
    frame as for a clip at once; one that fades in from pass-through, at the share shown."""
    n = 60
    roots = np.stack([np.zeros(n), np.full(n, 100.0), 6.0 * np.arange(n)], axis=1)  # 6 cm a frame: a run
    settings = replace(FEET["input"], pace=((2.0, 1.5), (6.0, 3.0)))  # 0.75 at a walk, 0.5 at a run
    weights = np.zeros((n, 2))
    ankles = with_the_body(roots)
    body, feet = Pace(settings).track(roots, ankles, weights, np.ones(n))
    stream = Pace(settings)
    by_frame = [stream.track_one_frame(x, z, a[:, [0, 2]].tolist(), 0.0, 0.0, 1.0)
                for (x, _, z), a in zip(roots.tolist(), ankles)]
    np.testing.assert_allclose([f for _, f in by_frame], feet, atol=1e-12)
    by_frame = [body for body, _ in by_frame]
    np.testing.assert_allclose(by_frame, body, atol=1e-12)
    np.testing.assert_allclose(6.0 - np.diff(body[:, 1]), 3.0, atol=1e-9)  # half of each step
    faded, _ = Pace(settings).track(roots, ankles, weights, np.clip(np.arange(n) / 30.0, 0.0, 1.0))
    # a fade from pass-through starts at the share of the slowdown it shows on its first step
    assert 6.0 - faded[1, 1] == pytest.approx(6.0 * (1.0 - 0.5 / 30.0), abs=1e-9)


def test_the_planned_mix_spells_out_each_run():
    runs = [(0, 3, None, 0.0), (3, 2, None, np.array([0.25, 0.5])), (5, 1, None, 1.0)]
    assert planned_mix(runs, 6).tolist() == [0.0, 0.0, 0.0, 0.25, 0.5, 1.0]


@needs_data
def test_restyle_starts_a_paced_clip_where_its_input_starts_and_writes_the_shorter_path():
    from stylecast.models.data import bandai_skeleton
    from stylecast.models.restyle import restyle_rotations

    roots, q = held_out_walk()
    sk = bandai_skeleton(D.list_files(DATA))
    settings = replace(FEET["input"], pace=((travel_speed(roots), 0.8 * travel_speed(roots)),))
    out = restyle_rotations(q, lambda words: words, 4, roots=roots, skeleton=sk, contacts=settings)
    np.testing.assert_allclose(out.roots[0, [0, 2]], roots[0, [0, 2]], atol=1e-9)  # the mirrored lead-in taken off
    assert travel_speed(out.roots) == pytest.approx(0.8 * travel_speed(roots), rel=0.03)


def test_a_root_that_jumps_back_resets_the_lag_and_the_feet_go_with_the_body():
    """A looped clip starts over (or a tracker loses its origin): the avatar jumps with its
    performer and the lag starts again from nothing, instead of a stride's worth of metres
    left between the feet and the body."""
    n = 200
    z = 2.0 * (np.arange(n) % 100)  # walks 2 cm a frame for 100 frames, then jumps back 198 cm
    roots = np.stack([np.zeros(n), np.full(n, 100.0), z], axis=1)
    pace = Pace(replace(FEET["input"], pace=((2.0, 1.5), (6.0, 3.0))))  # 0.75 at a walk, 0.5 fast
    body, feet = pace.track(roots, with_the_body(roots), np.zeros((n, 2)))
    assert body[99, 1] > 10.0  # the lag built up over the first pass
    assert np.abs(body[100]).max() == 0.0 and np.abs(feet[100]).max() == 0.0  # reset at the jump
    # the second pass lags as the first ended, settling on 0.25 of each 2 cm step: the jump
    # did not enter the speed's low-pass (which would have read a fast pace, up to 0.5 of it)
    before, after = np.diff(body[:100, 1]), np.diff(body[100:, 1])
    assert after[0] == pytest.approx(before[-1], abs=0.005) and np.all(np.diff(after) >= -1e-12)
    assert after[-1] == pytest.approx(0.5, abs=0.01)


def test_a_foot_slows_in_step_with_its_own_swing_never_pulled_back():
    """At a steady pace a foot's shift grows by the slowdown's share of the input foot's own
    step: a lifting foot's speed keeps its one hump, scaled. The known-bad recurrence took
    the BODY's step while the foot was free (before 2026-11-30): as the foot lifted slowly,
    the body's step pulled it backwards, and its speed dipped mid-swing."""
    n, swing = 200, 30
    roots = np.stack([np.zeros(n), np.full(n, 100.0), 2.0 * np.arange(n)], axis=1)  # 2 cm a frame
    settings = replace(FEET["input"], pace=((2.0, 1.5),))  # 0.75 of the input's pace
    # a swing's speed, one hump: over a stance and a swing the foot goes as far as the body
    hump = 8.0 * np.sin(np.pi * (np.arange(swing) + 0.5) / swing) ** 2
    steps = np.tile(np.concatenate([np.zeros(swing), hump]), n // (2 * swing) + 1)[:n]  # plant, swing, ...
    ankles = np.zeros((n, 2, 3))
    ankles[:, :, 2] = np.cumsum(steps)[:, None]
    weights = np.repeat((steps == 0.0)[:, None], 2, axis=1).astype(np.float64)  # locked while planted
    body, feet = Pace(settings).track(roots, ankles, weights)
    world = ankles[:, 0, 2] - feet[:, 0, 1]  # where the foot goes: the input's ankle less its shift
    settled = slice(100, None)  # the pace's low-passes settled
    speed = np.diff(world)[settled]
    assert speed.min() >= 0.0  # never pulled back
    free = (weights[1:, 0] == 0.0)[settled]
    assert speed[free].max() == pytest.approx(0.75 * hump.max(), rel=0.1)  # the hump, scaled
    edges = np.flatnonzero(np.diff(np.concatenate([[0], free.astype(np.int8), [0]])))
    for a, b in zip(edges[::2], edges[1::2]):  # one hump per swing: no dip (metrics.swing_dips' test)
        v = speed[a:b]
        peak = int(np.argmax(v))
        assert np.all(np.diff(v[:peak + 1]) >= -1e-9) and np.all(np.diff(v[peak:]) <= 1e-9)
    # the old recurrence, the body's step while free: pulled back as the foot lifts
    body_step = np.diff(body[:, 1], prepend=0.0)
    old = np.zeros(n)
    for t in range(1, n):
        old[t] = old[t - 1] + (1.0 - weights[t, 0]) * (body_step[t] + 0.15 * (body[t - 1, 1] - old[t - 1]))
    assert np.diff(ankles[:, 0, 2] - old)[settled][free].min() < 0.0
