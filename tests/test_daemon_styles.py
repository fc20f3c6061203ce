"""Live style control of a multi-style model: serve --style, /stylecast/style and
/stylecast/mix over real loopback UDP, per-performer mixes in ONE batched model call,
the crossfade of a style change, and the status naming the mix."""

from __future__ import annotations

import logging
import socket
from dataclasses import replace

import numpy as np
import pytest
import torch

from stylecast.daemon.commands import parse_command
from stylecast.daemon.config import DaemonConfig
from stylecast.motion.footlock import FEET
from stylecast.daemon.engine import Daemon
from stylecast.daemon.restylers import IdentityRestyler, StandInRestyler
from stylecast.drivers.bvh.bvh_replay import ReplaySource
from stylecast.models.restyler import Restyler
from stylecast.models.restyler_multistyle import MultiStyleRestyler
from stylecast.models.gait_amplitude import ARM_SWING_TRIM, RAISED_SWAY_GAIN, amplitudes
from stylecast.models.pace import SLOWEST_WALK, pace_points
from stylecast.models.styles import STYLES, one_hot, parse_mix
from stylecast.models.train_multistyle import train_multistyle
from stylecast.motion.clock import FakeClock
from stylecast.motion.errors import UserError

from .test_daemon import run_daemon, walk_clip
from .test_daemon_control import osc, wait_for
from .test_multistyle import _tiny_cfg, _tiny_words


class Spy(MultiStyleRestyler):
    """The model, recording every call the daemon's model thread makes (its batch size and
    style weights)."""

    calls: list

    def restyle_stream_words(self, words, weights=None):
        self.calls.append((len(words), None if weights is None else np.array(weights)))
        return super().restyle_stream_words(words, *(() if weights is None else (weights,)))


@pytest.fixture(scope="module")
def tiny_multistyle(tmp_path_factory):
    torch.set_num_threads(1)
    out = tmp_path_factory.mktemp("multistyle")
    t = train_multistyle(_tiny_cfg(ema=0), out, _tiny_words(), device="cpu", progress=False, log=lambda *_: None)
    with torch.no_grad():  # one epoch barely moves the codes: make the styles differ clearly
        t.model.G.head.weight.add_(torch.randn_like(t.model.G.head.weight) * 0.05)
        for p in t.model.G.blocks.parameters():
            p.add_(torch.randn_like(p) * 0.05)
    t.save_models(out, {}, log=lambda *_: None)
    return out / "model.safetensors"


def spy(path) -> Spy:
    r = Restyler.load(path)
    s = Spy(r.model, r.rep, r.metadata, r.weights, r.path)
    s.calls = []
    return s


def make(restyler, style="", performer_style=""):
    cfg = DaemonConfig(hop=15, control="127.0.0.1:0", allow=["127.0.0.1"], style=style,
                       performer_style=performer_style)
    sources = [ReplaySource(walk_clip(900, seed=k), name, loop=True) for k, name in enumerate(("alice", "bob"))]
    return Daemon(cfg, sources, restyler, FakeClock(), log_status=False)


def test_style_and_mix_commands_parse_from_the_one_table():
    assert parse_command("/stylecast/style", "s", ("elderly",)) == ("style", (("elderly", 1.0),), None)
    assert parse_command("/stylecast/style", "sfs", ("elderly", 0.25, "bob")) == \
        ("style", (("elderly", 0.25), ("normal", 0.75)), "bob")
    assert parse_command("/stylecast/style", "ss", ("elderly", "bob")) == ("style", (("elderly", 1.0),), "bob")
    assert parse_command("/stylecast/mix", "sfsf", ("elderly", 0.5, "youthful", 0.5)) == \
        ("mix", (("elderly", 0.5), ("youthful", 0.5)), None)
    assert parse_command("/stylecast/mix", "sfsfs", ("elderly", 1, "youthful", 3, "alice"))[2] == "alice"
    for address, args in (("/stylecast/style", ()), ("/stylecast/style", ("elderly", 1.5)),
                          ("/stylecast/style", ("elderly", float("nan"))), ("/stylecast/mix", ("elderly",)),
                          ("/stylecast/mix", ("elderly", "youthful")), ("/stylecast/mix", ("elderly", -1.0)),
                          ("/stylecast/mix", ("x", 1.0) * 17)):
        assert parse_command(address, "", args) == (None, "bad_arguments"), args


def test_serve_style_is_checked_before_anything_opens():
    with pytest.raises(UserError, match="unknown style 'sleepy'.*youthful"):
        DaemonConfig(style="sleepy").validate()
    with pytest.raises(UserError, match="no styles to choose"):
        make(StandInRestyler(), style="elderly")


def test_serve_performer_style_is_checked_before_anything_opens_and_a_pair_model_refuses_another_source():
    with pytest.raises(UserError, match="unknown performer style 'sleepy'.*youthful, or auto to have it read"):
        DaemonConfig(performer_style="sleepy").validate()
    pair = Restyler.load("normal2exhausted")
    with pytest.raises(UserError, match="restyles normal input in this direction, not elderly"):
        make(pair, performer_style="elderly")


def _served(restyler, **config) -> dict:
    """Every frame the daemon sends for two performers replaying a walk (virtual clock)."""
    _, frames = run_daemon(walk_clip(240), restyler, hop=15, performers=2, **config)
    return {k: np.array([np.concatenate([np.ravel(f.rotations), np.ravel(f.root_position)]) for f in v])
            for k, v in frames.items()}


def _largest_difference(a: dict, b: dict) -> float:
    assert a.keys() == b.keys() and all(len(a[k]) == len(b[k]) > 200 for k in a)
    return max(float(np.abs(a[k] - b[k]).max()) for k in a)


def test_the_performers_own_style_is_served_as_performed(tiny_multistyle):
    """``serve --model multistyle`` before any style is chosen (the neutral style) sends the
    input, and so does a style the performers are told they move in; the generator's own
    code for that style moved them (the known-bad case, ``code_and_intensity``)."""
    model = Restyler.load(tiny_multistyle)
    as_performed = _served(IdentityRestyler())
    assert _largest_difference(_served(model), as_performed) < 1e-5
    assert _largest_difference(_served(model, style="elderly", performer_style="elderly"), as_performed) < 1e-5
    assert _largest_difference(_served(model, style="elderly"), as_performed) > 1e-2


def test_a_stream_starts_as_its_model_ships_it_the_multistyle_models_faded_in(tiny_multistyle):
    """A stream's first frame is shown restyled (``BlendSettings.start_restyled``), but the
    multistyle model's first words, mostly the first pose held, popped when shown at once
    (the model card), so its streams fade in; a performer who starts after a switch of model
    starts as the new model ships it."""
    def first_mix(daemon):
        while daemon.sessions[0].frames_out < 1:
            daemon.step()
        return daemon.sessions[0].blender.mix

    multistyle = make(Restyler.load(tiny_multistyle), style="elderly")
    assert multistyle.settings.start_restyled is False
    assert first_mix(multistyle) == pytest.approx(1 / multistyle.settings.crossfade_frames)  # one fade step
    multistyle.close()
    pair = make(StandInRestyler())
    assert first_mix(pair) == 1.0  # restyled from the first frame
    pair._pending_model = Restyler.load(tiny_multistyle)  # what /stylecast/model hands the clock's thread
    pair._apply_control()
    assert pair.settings.start_restyled is False
    pair.close()


def test_live_styles_over_udp_one_batched_call_crossfade_and_status(tiny_multistyle, caplog):
    model = spy(tiny_multistyle)
    daemon = make(model, style="youthful")  # serve --style youthful: the model's own mix
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    port = daemon.control.address[1]
    caplog.set_level(logging.WARNING, logger="stylecast.daemon")
    try:
        daemon.start()
        for _ in range(120):
            daemon.step()
        assert model.calls and all(w is None for _, w in model.calls)  # nobody chose: the model's own (youthful) for all
        assert np.allclose(daemon.worker.restyler.weights, one_hot("youthful"))
        # --feet auto: a multistyle model's sessions keep the restyled stance (motion.footlock.FEET),
        # at the pace of the style they are given (--pace style)
        assert all(s.feet.settings == replace(FEET["stance"], pace=pace_points("normal", {"youthful": 1.0}),
                                              **amplitudes("normal", {"youthful": 1.0}))
                   for s in daemon.sessions)
        assert all(s.feet.amplitude._across.on for s in daemon.sessions)  # youthful's swing across replaced
        accepted = daemon.control.counts["accepted"]
        client.sendto(osc("/stylecast/style", "elderly", "alice"), ("127.0.0.1", port))
        client.sendto(osc("/stylecast/mix", "active", 0.5, "masculine", 0.5, "bob"), ("127.0.0.1", port))
        client.sendto(osc("/stylecast/style", "sleepy"), ("127.0.0.1", port))
        assert wait_for(lambda: daemon.control.counts["accepted"] >= accepted + 3)
        # A word submitted before the change may still be in the model's thread (it was, once,
        # on a loaded machine): it belongs to before the change.
        assert daemon.worker.wait_idle(5.0)
        before = len(model.calls)
        for _ in range(150):
            daemon.step()
        calls = model.calls[before:]
        # Both performers' words in one call per tick, each row with its own mix.
        assert calls and all(n == 2 for n, _ in calls) and daemon.worker.faults == 0
        first, last = calls[0][1], calls[-1][1]
        assert np.allclose(last[0], one_hot("elderly")) and np.allclose(last[1], parse_mix("active:1,masculine:1"))
        # The crossfade (0.5 s = 30 frames, a word every 15): the first word after the
        # change is half youthful (the model's own mix), half elderly; the elderly weight
        # only grows, and reaches 1 one crossfade after the change.
        e, y = STYLES.index("elderly"), STYLES.index("youthful")
        assert first[0, y] == pytest.approx(0.5) and first[0, e] == pytest.approx(0.5)
        elderly = [w[0, e] for _, w in calls]
        assert np.all(np.diff(elderly) >= 0) and elderly[1] == 1.0 and elderly[-1] == 1.0
        lines = daemon.status_lines()
        assert "elderly" in lines[0] and "active 0.50 + masculine 0.50" in lines[1]
        # each performer's pace moved to its own style's: elderly walks slower; active and
        # masculine walk faster, and a pace only slows (footlock.MAX_PACE_RATIO)
        walk = 109.8 / 60  # cm a frame, the normal walks' pace
        alice, bob = (s.feet.pace.ratio(walk) for s in daemon.sessions)
        assert alice == pytest.approx(SLOWEST_WALK) and bob == 1.0  # elderly walks: the slowest a walk is made
        # ...and its hips to its own style's (MultiStyleRestyler.quick_hips_of_style, by the
        # mix's weights): bob's mix is half masculine (all quick) and half active (half quick);
        # elderly asks for none
        assert [s.feet.pelvis.quick_share for s in daemon.sessions] == [0.0, 0.75]
        # ...and keeps its own style's share of the stance standing (``standing_stance_of_style``):
        # bob's half active (none of it) and half masculine (all of it)
        assert [s.feet.stance.standing for s in daemon.sessions] == [1.0, 0.5]
        # ...and its arms swing and hips bob as its own style's (models/gait_amplitude.py):
        # alice's walks half as far, bob's arms half active's and half masculine's (trimmed,
        # ARM_SWING_TRIM); his hips would bob twice as much, and a bob only lessens
        # (footlock MAX_BOB_GAIN)
        trimmed = ARM_SWING_TRIM["masculine"][0] * 13.90
        assert [s.feet.amplitude.gains(walk) for s in daemon.sessions] == pytest.approx(
            [(7.09 / 13.84, 0.69 / 1.28), ((16.25 + trimmed) / 2 / 13.84, 1.0)])
        # ...and neither new mix replaces the hands' swing across, which youthful did; bob's
        # raised hands sway by half active's gain for a raise (masculine keeps the restyle's)
        assert [s.feet.amplitude._across.on for s in daemon.sessions] == [False, False]
        assert [s.feet.amplitude._raise.at(0.0) for s in daemon.sessions] == pytest.approx(
            [1.0, (1.0 + RAISED_SWAY_GAIN["active"][1]) / 2])
        assert any("unknown style 'sleepy'" in r.getMessage() and "youthful" in r.getMessage() for r in caplog.records)
        # The delivered words are the model's own answer for each row's mix.
        word = np.stack([walk_clip(60).rotations])
        together = model.restyle_words(np.concatenate([word, word]), np.stack([one_hot("elderly"), one_hot("active")]))
        assert np.allclose(together[0], model.with_style("elderly").restyle_words(word)[0], atol=1e-6)
        assert not np.allclose(together[0], together[1], atol=1e-4)
    finally:
        daemon.close()
        client.close()


def test_a_style_command_to_a_model_without_codes_is_refused_in_one_sentence():
    daemon = make(StandInRestyler())
    try:
        with pytest.raises(UserError, match="no style codes to mix; load the multistyle model"):
            daemon.apply("style", (("elderly", 1.0),))
    finally:
        daemon.close()


def test_the_viewer_reads_the_style_mix_from_the_status_reply_and_older_daemons_still_parse():
    from stylecast.daemon.status import status_messages
    from stylecast.viewer.status import parse_status

    perf = {"performer": "alice", "frames_in": 10, "frames_out": 9, "latency_p50_ms": 80.0, "latency_p99_ms": 90.0,
            "late": 0, "held": 0, "skipped": 0, "words_failed": 0, "intensity": 1.0, "bypass": False, "lost": False,
            "style": "elderly 0.50 + youthful 0.50"}
    snap = {"daemon": {"style": "any->normal", "model": "multistyle", "performers": 1, "ticks": 10,
                       "dropped_ticks": 0, "faults": 0, "control_refused": 0}, "performers": [perf]}
    tagged = [(a, "".join("s" if isinstance(v, str) else "f" if isinstance(v, float) else "i" for v in args), args)
              for a, args in status_messages(snap)]
    status = parse_status(tagged)
    assert status.performers[0].style == "elderly 0.50 + youthful 0.50"
    old = [(a, t[:12], args[:12]) for a, t, args in tagged]  # a daemon from before the style mix
    assert parse_status(old).performers[0].style == ""
