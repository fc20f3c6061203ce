"""The shared window-and-blend algorithm (motion/words.py)."""

import numpy as np
import pytest

from stylecast.motion import rotations as rot
from stylecast.motion.hinges import keep_hinges
from stylecast.motion.smoothing import CorrectionFilter, filter_frames
from stylecast.motion.words import (BlendSettings, SeamBlender, WordCutter, cut_words, half_rate_shift, render_planned,
                                   restyle_stream)

J = 22


def smooth_motion(frames: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rot.from_euler(np.cumsum(rng.normal(0, 0.6, (frames, J, 3)), axis=0), "ZXY")


def biased_restyler(seed: int = 1, degrees: float = 10.0):
    """A stand-in restyler whose words disagree with each other: each word gets its own
    constant rotation offset, which makes a hard seam at every word switch."""
    rng = np.random.default_rng(seed)

    def restyle(words):
        offset = rot.from_euler(rng.normal(0, degrees, (len(words), 1, J, 3)), "ZXY")
        return rot.multiply(np.broadcast_to(offset, words.shape), words)

    return restyle


def seam_ratio(out: np.ndarray, hop: int, skip: int = 120) -> float:
    step = rot.angle_between(out[1:], out[:-1]).mean(axis=1)  # step[i]: frame i -> i+1
    switch = np.zeros(len(step), bool)
    switch[[e for e in range(59, len(step), hop)]] = True  # frame e+1 is the new word's first
    keep = np.arange(len(step)) >= skip
    return step[switch & keep].mean() / step[~switch & keep].mean()


def test_cutter_emits_words_on_the_hop_grid_from_the_start_with_the_first_frame_held_before_it():
    cutter = WordCutter(hop=15)
    motion = smooth_motion(100)
    words = [out for t in range(100) if (out := cutter.push(motion[t])) is not None]
    assert [end for end, _ in words] == [14, 29, 44, 59, 74, 89]  # the grid 59 + 15 k, from frame 0 on
    end, first = words[0]
    assert first.shape == (60, J, 4)
    assert rot.angle_between(first[:45], np.broadcast_to(motion[0], (45, J, 4))).max() < 1e-9  # frame 0, held
    assert rot.angle_between(first[45:], motion[:15]).max() < 1e-9  # then the stream so far
    assert rot.angle_between(words[3][1], motion[:60]).max() < 1e-9  # the first word of real frames only
    offline_ends, offline = cut_words(motion, hop=15)  # restyle's whole-clip cut: the same words
    assert offline_ends.tolist() == [end for end, _ in words]
    assert rot.angle_between(offline, np.stack([w for _, w in words])).max() < 1e-9


def test_cutter_words_are_the_last_60_frames_made_continuous_bit_for_bit():
    """The ring the cutter keeps gives exactly the window of the last 60 frames (the first
    frame held before the stream), each quaternion's sign chosen to continue the previous
    frame's, whatever signs the stream sent."""
    rng = np.random.default_rng(4)
    motion = smooth_motion(200) * rng.choice([-1.0, 1.0], (200, J, 1))  # q and -q: the same pose
    held = np.concatenate([np.repeat(motion[:1], 59, axis=0), motion])  # frame 0 held before it
    cutter = WordCutter(hop=7)
    words = [out for t in range(200) if (out := cutter.push(motion[t])) is not None]
    assert len(words) > 20 and words[-1][0] > 120  # the ring has wrapped several times
    for end, word in words:
        assert np.array_equal(word, rot.canonical_hemisphere(held[end:end + 60]))
        assert (np.sum(word[1:] * word[:-1], axis=-1) >= 0).all()
    assert not (np.sum(held[1:] * held[:-1], axis=-1) >= 0).all()  # the input was not


def test_identity_restyler_is_transparent():
    motion = smooth_motion(300)
    out = restyle_stream(motion, lambda w: w, BlendSettings(hop=15)).rotations
    assert rot.angle_between(out, motion).max() < 1e-6


@pytest.mark.parametrize("hop", [5, 15, 30])
def test_offset_blend_removes_the_seam_that_plain_switching_shows(hop):
    motion = smooth_motion(600)
    # the blender alone: the correction filter after it would hide plain switching too
    blended = restyle_stream(motion, biased_restyler(), BlendSettings(hop=hop, correction_tau=0)).rotations
    plain = restyle_stream(motion, biased_restyler(), BlendSettings(hop=hop, decay_frames=0, correction_tau=0)).rotations
    assert seam_ratio(blended, hop) < 1.10
    assert seam_ratio(plain, hop) > 3.0


@pytest.mark.parametrize("hop", [1, 15])
def test_output_follows_the_restyled_words_between_seams(hop):
    """Also at hop 1, where a word switch comes every frame: the offset must still
    settle, or the output would keep the input's pose and only borrow the words' motion."""
    motion = smooth_motion(400)
    constant = rot.from_euler(np.full((J, 3), 20.0), "ZXY")
    out = restyle_stream(motion, lambda w: rot.multiply(np.broadcast_to(constant, w.shape), w), BlendSettings(hop=hop)).rotations
    # ...as far as the elbows' and knees' hinges let it (``hinges``: a constant turn of
    # every bone bends them sideways too).
    expected = keep_hinges(motion, rot.multiply(np.broadcast_to(constant, motion.shape), motion))
    # The seam offset left by the fade-in settles exponentially (time constant <= 15 frames).
    assert rot.angle_between(out[300:], expected[300:]).max() < 1e-3


def test_a_stream_is_restyled_from_its_first_frame_without_a_transient():
    """A stream's first words hold its first frame before it, so frame 0 has a word, and
    nothing was shown before it: it is shown restyled, the correction's low-pass settled on
    it (growing in from nothing, a 56-degree correction came in at up to 7 degrees a frame)."""
    motion = smooth_motion(200)
    constant = rot.from_euler(np.full((J, 3), 30.0), "ZXY")
    out = restyle_stream(motion, lambda w: rot.multiply(np.broadcast_to(constant, w.shape), w),
                         BlendSettings(hop=15)).rotations
    expected = keep_hinges(motion, rot.multiply(np.broadcast_to(constant, motion.shape), motion))
    assert rot.angle_between(out[:60], expected[:60]).max() < 1e-6  # whole from frame 0
    jumps = rot.angle_between(out[1:], out[:-1]).max(axis=1)
    natural = rot.angle_between(expected[1:], expected[:-1]).max(axis=1)
    assert np.abs(jumps - natural).max() < 1e-6


def test_a_stream_asked_to_fade_in_fades_from_the_first_frame_without_a_jump():
    """``start_restyled=False``: the restyle fades in from frame 0 and is whole after the
    crossfade (before the first words held the first frame: pass-through for the first word,
    the fade ending at frame 65 here, a third of the clip)."""
    motion = smooth_motion(200)
    settings = BlendSettings(hop=15, crossfade_frames=20, start_restyled=False)
    constant = rot.from_euler(np.full((J, 3), 30.0), "ZXY")
    out = restyle_stream(motion, lambda w: rot.multiply(np.broadcast_to(constant, w.shape), w), settings).rotations
    expected = keep_hinges(motion, rot.multiply(np.broadcast_to(constant, motion.shape), motion))
    step = rot.angle_between(constant, rot.identity(())).max() / 20  # 30 deg about 3 axes (56 deg) over 20 frames
    assert rot.angle_between(out[0], motion[0]).max() < step + 1e-6  # one crossfade step in
    assert rot.angle_between(out[1], motion[1]).max() > 0.3  # the fade has begun at once
    whole = settings.first_fade_end  # the crossfade and the correction's low-pass after it
    assert rot.angle_between(out[whole:60], expected[whole:60]).max() < 0.1
    jumps = rot.angle_between(out[1:], out[:-1]).max(axis=1)
    natural = rot.angle_between(motion[1:], motion[:-1]).max(axis=1)
    assert (jumps - natural).max() < step + 1.0


def test_late_word_fades_to_pass_through_and_back_without_pop():
    motion = smooth_motion(400)
    settings = BlendSettings(hop=15, crossfade_frames=10)
    cutter, blender = WordCutter(15), SeamBlender(settings, J)
    constant = rot.from_euler(np.full((J, 3), 25.0), "ZXY")
    out = []
    for now in range(400 + settings.delay):  # as live: frame t is rendered at time t + delay
        if now < 400:
            made = cutter.push(motion[now])
            if made is not None and not 150 <= made[0] <= 200:  # these words never arrive
                blender.add_word(made[0], rot.multiply(np.broadcast_to(constant, made[1].shape), made[1]))
        t = now - settings.delay
        if 0 <= t < 400 - settings.hop:
            out.append(blender.render(t, motion[t]))
    out = np.stack(out)
    assert blender.late_frames > 0
    steps = rot.angle_between(out[1:], out[:-1]).max(axis=1)
    natural = rot.angle_between(motion[1:len(out)], motion[:len(out) - 1]).max(axis=1)
    assert (steps - natural).max() < 45.0 / 10 + 1.0
    assert rot.angle_between(out[190], motion[190]).max() < 1e-6  # faded fully to pass-through
    expected = rot.multiply(np.broadcast_to(constant, motion.shape), motion)
    assert rot.angle_between(out[330:], expected[330:len(out)]).max() < 1e-3  # and back to restyled


def test_settings_are_validated():
    with pytest.raises(ValueError, match="hop"):
        BlendSettings(hop=0)
    with pytest.raises(ValueError, match="delay"):
        BlendSettings(hop=15, delay=5)


def test_frame_by_frame_rendering_equals_block_rendering():
    """The daemon renders (and low-passes the correction of) one frame per tick, restyle
    whole clips: same frames."""
    motion = smooth_motion(500)
    settings = BlendSettings(hop=10)
    block = restyle_stream(motion, biased_restyler(seed=4), settings).rotations
    restyle = biased_restyler(seed=4)
    cutter, blender, out = WordCutter(10), SeamBlender(settings, J), []
    smoothing = CorrectionFilter(J, settings.correction_tau)
    for now in range(500 + settings.delay):
        if now < 500:
            made = cutter.push(motion[now])
            if made is not None:
                blender.add_word(made[0], restyle(made[1][None])[0])
        if 0 <= now - settings.delay < 500 - settings.hop:
            t = now - settings.delay
            out.append(keep_hinges(motion[t], smoothing.apply(motion[t][None], blender.render(t, motion[t])[None])[0]))
    assert rot.angle_between(np.stack(out), block[:len(out)]).max() < 1e-9


def test_blenders_rendered_together_a_frame_a_tick_equal_each_rendered_alone():
    """The daemon renders every performer's frame of a tick in one call (``render_planned``):
    three streams on other word grids, one faded to pass-through half-way and back, one at
    half intensity with a faster seam spring; each equals its own blender rendering its
    frames alone."""
    motions = [smooth_motion(300, seed=k) for k in range(3)]
    restyle = biased_restyler(seed=2)
    settings = [BlendSettings(hop=10, phase=p, decay_frames=d) for p, d in ((0, None), (3, None), (7, 4.0))]
    intensity = [1.0, 1.0, 0.5]
    pairs = [(SeamBlender(s, J), SeamBlender(s, J)) for s in settings]
    cutters = [WordCutter(10, phase=s.phase) for s in settings]
    together, alone = [[] for _ in motions], [[] for _ in motions]
    delay = settings[0].delay
    mixes = []
    for now in range(300):
        for k, (motion, cutter) in enumerate(zip(motions, cutters)):
            made = cutter.push(motion[now])
            if made is not None:
                word = restyle(made[1][None])[0]
                pairs[k][0].add_word(made[0], word)
                pairs[k][1].add_word(made[0], word)
        t = now - delay
        if t < 0:
            continue
        active = [True, not 120 <= t < 150, True]
        items = [(a, a.plan_block(t, m[t][None], i, on), m[t][None])
                 for (a, _), m, i, on in zip(pairs, motions, intensity, active)]
        mixes.append(pairs[1][0].mix)
        for k, frame in enumerate(render_planned(items)):
            together[k].append(frame[0])
            alone[k].append(pairs[k][1].render(t, motions[k][t], intensity[k], active[k]))
    for k in range(3):
        assert rot.angle_between(np.stack(together[k]), np.stack(alone[k])).max() < 1e-9
        assert rot.angle_between(np.stack(together[k])[200:], motions[k][200:300 - delay]).max() > 1.0  # restyled
    assert min(mixes[120:200]) < 1e-9 and mixes[-1] == 1.0  # the second stream faded out and came back


def test_phase_shifts_the_word_grid_and_the_blend_follows_it():
    motion = smooth_motion(300)
    cutter = WordCutter(hop=15, phase=7)
    ends = [out[0] for t in range(300) if (out := cutter.push(motion[t])) is not None]
    assert ends[:3] == [6, 21, 36]  # the grid 66 + 15 k, one phase later than at phase 0
    constant = rot.from_euler(np.full((J, 3), 20.0), "ZXY")
    settings = BlendSettings(hop=15, phase=7)
    blender = SeamBlender(settings, J)
    assert [blender.serving_word(t) for t in (0, 6, 7, 21, 22)] == [6, 6, 21, 21, 36]
    out = restyle_stream(motion, lambda w: rot.multiply(np.broadcast_to(constant, w.shape), w), settings).rotations
    assert rot.angle_between(out[1], motion[1]).max() > 0  # the fade-in has begun at the start
    assert rot.angle_between(out[30], motion[30]).max() > 5.0
    with pytest.raises(ValueError, match="phase"):
        BlendSettings(hop=15, phase=15)


@pytest.mark.parametrize("hop", range(1, 21))
@pytest.mark.parametrize("phase_share", [0.0, 0.3, 0.5, 0.9])
def test_a_half_rate_streams_held_start_puts_every_word_end_on_a_source_frame(hop, phase_share):
    """A 30 fps source's frames are the even ones of its 60 Hz stream; after the held copies
    ``half_rate_shift`` gives, every word the cutter emits ends on one of them (that is
    what lets the daemon show the stream a period sooner); an odd hop cannot have it."""
    phase = int(phase_share * hop)
    shift = half_rate_shift(hop, phase=phase)
    if hop % 2:
        assert shift is None
        return
    cutter = WordCutter(hop=hop, phase=phase)
    ends = [out[0] for t in range(200) if (out := cutter.push(rot.identity((J,)))) is not None]
    assert shift in (0, 1) and len(ends) > 5
    assert all((end - shift) % 2 == 0 for end in ends), (ends[:4], shift)
    assert all((end - (1 - shift)) % 2 == 1 for end in ends)  # the other choice puts them all on interpolated ones


def test_the_correction_filter_removes_a_shaking_correction_and_keeps_a_steady_one():
    """A correction that flips every few frames (words that disagree) comes out smooth; a
    constant one (a posture change) comes through whole once settled; and the input's own
    motion is untouched."""
    motion = smooth_motion(300)
    bias = rot.from_euler(np.full((J, 3), 8.0), "ZXY")
    steady = rot.multiply(bias, motion)
    flip = np.where((np.arange(300) // 4 % 2 == 0)[:, None, None], steady, motion)  # 8 deg on and off every 4 frames
    smooth = CorrectionFilter(J).apply(motion, flip)
    jerk = lambda q: np.abs(np.diff(rot.log_map(rot.multiply(q, rot.inverse(motion))), n=3, axis=0)).mean()
    assert jerk(smooth) < 0.05 * jerk(flip)
    settled = CorrectionFilter(J).apply(motion, steady)
    assert rot.angle_between(settled[60:], steady[60:]).max() < 1e-3  # a steady correction passes whole
    assert rot.angle_between(CorrectionFilter(J).apply(motion, motion), motion).max() < 1e-9
    assert CorrectionFilter(J, tau=0).apply(motion, flip) is flip  # off


def test_streams_filtered_together_a_frame_a_tick_equal_each_filtered_alone():
    """The daemon low-passes every performer's frame of a tick in one call (``filter_frames``);
    each stream must come out as its own filter run over its whole clip."""
    motions = [smooth_motion(120, seed=k) for k in range(3)]
    restyled = [rot.multiply(rot.from_euler(np.full((J, 3), 5.0 * (k + 1)), "ZXY"), m) for k, m in enumerate(motions)]
    filters = [CorrectionFilter(J) for _ in motions]
    got = np.stack([filter_frames(filters, np.stack([m[t] for m in motions]), np.stack([r[t] for r in restyled]))
                    for t in range(120)], axis=1)  # (3, 120, J, 4)
    for k, (m, r) in enumerate(zip(motions, restyled)):
        expected = CorrectionFilter(J).apply(m, r)
        assert rot.angle_between(got[k], expected).max() < 1e-9
        assert rot.angle_between(got[k, 60:], r[60:]).max() < 1e-3  # each settled on its own correction
    mixed = [CorrectionFilter(J), CorrectionFilter(J, tau=0)]  # different settings: each its own way
    out = filter_frames(mixed, np.stack([motions[0][0]] * 2), np.stack([restyled[0][0]] * 2))
    assert rot.angle_between(out[1], restyled[0][0]).max() < 1e-9



def test_blenders_planned_together_a_frame_a_tick_equal_each_planned_alone():
    """The daemon plans every performer's frame of a tick in one ``plan_frames`` call (the
    seam springs and the switches of word as arrays for all); each blender must plan what
    its own ``plan_block`` plans: the same runs, the same output, the same state after,
    through switches, late words, a crossfade, an intensity change and blending off."""
    from stylecast.motion.words import plan_frames

    motions = [smooth_motion(200, seed=k) for k in range(4)]
    settings = [BlendSettings(hop=4, delay=5), BlendSettings(hop=4, delay=5, phase=2),
                BlendSettings(hop=15, delay=15), BlendSettings(hop=4, delay=5, decay_frames=0)]
    restyle = biased_restyler()
    pairs = []
    for motion, s in zip(motions, settings):
        ends, words = cut_words(motion, s.hop, s.word_length, s.phase)
        restyled = restyle(words)
        pairs.append([(SeamBlender(s, J), SeamBlender(s, J)), ends, restyled])
    for t in range(200):
        for k, ((together, alone), ends, restyled) in enumerate(pairs):
            for end, word in zip(ends, restyled):
                # words arrive as the frames they end on come in, except a gap of late words
                if end == t + settings[k].delay - settings[k].hop and not 90 <= end < 110:
                    together.add_word(int(end), word)
                    alone.add_word(int(end), word)
        intensity = 1.0 if t < 150 else 0.6
        items = [(together, t, m[t], intensity, t < 170 or k % 2) for k, ((together, _), _, _), m
                 in zip(range(4), pairs, motions)]
        planned = plan_frames(items)
        for (together, alone), runs, (_, _, x, _, active) in zip((p[0] for p in pairs), planned, items):
            expected = alone.plan_block(t, x[None], intensity, active)
            got = render_planned([(together, runs, x[None])])[0]
            want = render_planned([(alone, expected, x[None])])[0]
            assert rot.angle_between(got, want).max() < 1e-9, t
            assert [r[:2] for r in runs] == [r[:2] for r in expected]
            np.testing.assert_allclose(together._offset, alone._offset, atol=1e-12)
            np.testing.assert_allclose(together._offset_velocity, alone._offset_velocity, atol=1e-12)
            assert (together.mix, together.late_frames, together._serving) == (alone.mix, alone.late_frames,
                                                                             alone._serving)
    assert all(p[0][0].late_frames > 0 for p in pairs)  # the gap really went through the late path
