"""The OSC control port over real loopback UDP: commands, status reply, allow-list."""

from __future__ import annotations

import socket
import time

import numpy as np
from pythonosc.osc_bundle import OscBundle
from pythonosc.osc_message import OscMessage
from pythonosc.osc_message_builder import OscMessageBuilder

from stylecast.motion.clock import FakeClock
from stylecast.daemon.config import DaemonConfig
from stylecast.daemon.commands import COMMANDS
from stylecast.daemon.control import ControlServer
from stylecast.daemon.engine import Daemon
from stylecast.daemon.restylers import StandInRestyler
from stylecast.drivers.bvh.bvh_replay import ReplaySource
from stylecast.motion import rotations as rot

from .test_daemon import walk_clip


def osc(address, *args) -> bytes:
    b = OscMessageBuilder(address)
    for a in args:
        b.add_arg(a)
    return b.build().dgram


def make_daemon(frames, allow=("127.0.0.1",)):
    cfg = DaemonConfig(hop=15, control="127.0.0.1:0", allow=list(allow))
    return Daemon(cfg, [ReplaySource(walk_clip(600), "alice", loop=True)], StandInRestyler(), FakeClock(),
                  frame_taps=[frames.append], log_status=False)


def wait_for(predicate, timeout=3.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.005)
    return False


def test_control_commands_crossfade_and_status_replies():
    frames = []
    daemon = make_daemon(frames)
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.bind(("127.0.0.1", 0))
    client.settimeout(2.0)
    port = daemon.control.address[1]
    try:
        daemon.start()
        for _ in range(150):
            daemon.step()
        accepted = daemon.control.counts["accepted"]
        client.sendto(osc("/stylecast/intensity", 0.0), ("127.0.0.1", port))
        assert wait_for(lambda: daemon.control.counts["accepted"] > accepted)
        for _ in range(100):
            daemon.step()
        assert daemon.sessions[0].intensity == 0.0 and daemon.sessions[0].blender.mix == 0.0
        client.sendto(osc("/stylecast/bypass", 1, "alice"), ("127.0.0.1", port))
        client.sendto(osc("/stylecast/intensity", 1.0), ("127.0.0.1", port))
        client.sendto(osc("/stylecast/bypass", 0), ("127.0.0.1", port))
        assert wait_for(lambda: daemon.control.counts["accepted"] >= accepted + 4)
        for _ in range(150):
            daemon.step()
        assert daemon.sessions[0].blender.mix == 1.0
        client.sendto(osc("/stylecast/status"), ("127.0.0.1", port))
        assert wait_for(lambda: len(daemon.control.commands) > 0)
        daemon.step()
        reply, _ = client.recvfrom(65536)
    finally:
        daemon.close()
        client.close()
    messages = {m.address: m.params for m in OscBundle(reply)} if OscBundle.dgram_is_bundle(reply) \
        else {OscMessage(reply).address: OscMessage(reply).params}
    perf = messages["/stylecast/status/performer"]
    assert perf[0] == "alice" and perf[1] == 400 and perf[2] == 400 - 15  # read at the start of tick 400
    assert messages["/stylecast/status/daemon"][0] == "standin"
    live = np.stack([f.rotations for f in frames])
    inputs = np.stack([daemon.sessions[0].source.rotations[f.index % 600] for f in frames])
    steps = rot.angle_between(live[1:], live[:-1]).max(axis=1)
    in_steps = rot.angle_between(inputs[1:], inputs[:-1]).max(axis=1)
    assert (steps - in_steps).max() < 1.5  # every change faded, nothing popped


def test_a_sender_outside_the_allow_list_is_refused_and_counted(caplog):
    frames = []
    daemon = make_daemon(frames, allow=("10.0.0.0/8",))
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        daemon.start()
        for _ in range(2):
            client.sendto(osc("/stylecast/bypass", 1), daemon.control.address)
        assert wait_for(lambda: daemon.control.refused == 2)
        for _ in range(5):
            daemon.step()
        assert daemon.sessions[0].bypass is False
        assert daemon.snapshot()["daemon"]["control_refused"] == 2
    finally:
        daemon.close()
        client.close()
    assert sum("not in the allow-list" in r.getMessage() for r in caplog.records) == 1  # logged once


def test_malformed_and_unknown_control_packets_are_counted_not_fatal():
    server = ControlServer("127.0.0.1", 0)
    try:
        addr = ("127.0.0.1", 5555)
        for data in (b"", b"garbage!", osc("/stylecast/nope", 1), osc("/stylecast/intensity", "x"),
                     osc("/stylecast/intensity", float("nan")), b"#bundle\x00" + b"\x00" * 7 + b"\x01\xff\xff\xff\xff"):
            server.handle(data, addr)
        server.handle(osc("/stylecast/intensity", 0.5), addr)
        assert [c[:2] for c in server.drain()] == [("intensity", 0.5)]
        assert server.counts["unknown_address"] == 1 and server.counts["bad_arguments"] == 2
        assert sum(v for k, v in server.counts.items() if k.startswith("malformed_")) == 3
    finally:
        server.close()


def test_a_wrong_command_gets_one_sentence_with_its_usage_then_is_only_counted(caplog):
    # Once silent: a Stream Deck button sending /stylecast/style elderly 5.0 did nothing
    # and said nothing. Over a real socket, each wrong command three times.
    server = ControlServer("127.0.0.1", 0)
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        wrong = [osc("/stylecast/style", "elderly", 5.0), osc("/stylecast/intensity", "loud"),
                 osc("/stylecast/styel", "elderly")]
        for data in wrong * 3:
            client.sendto(data, server.address)
        assert wait_for(lambda: server.counts["bad_arguments"] == 6 and server.counts["unknown_address"] == 3)
    finally:
        server.close()
        client.close()
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith("control: ")]
    later = " (more within 10 s are counted, not logged)"
    assert lines == [
        "control: /stylecast/style takes s style [f weight (0 to 1)] [s performer]; ignored" + later,
        "control: /stylecast/intensity takes f value (0 to 1) [s performer]; ignored" + later,
        "control: unknown address '/stylecast/styel'; the known ones are " + ", ".join(COMMANDS) + later]


def test_crossfade_over_the_socket_changes_the_next_fade_of_every_performer():
    cfg = DaemonConfig(hop=15, control="127.0.0.1:0", crossfade=0.5)
    sources = [ReplaySource(walk_clip(600), name, loop=True) for name in ("alice", "bob")]
    daemon = Daemon(cfg, sources, StandInRestyler(), FakeClock(), log_status=False)
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    port = daemon.control.address[1]
    try:
        daemon.start()
        for _ in range(150):
            daemon.step()
        assert [s.blender.mix for s in daemon.sessions] == [1.0, 1.0]
        client.sendto(osc("/stylecast/crossfade", 2.0), ("127.0.0.1", port))
        client.sendto(osc("/stylecast/bypass", 1), ("127.0.0.1", port))
        assert wait_for(lambda: len(daemon.control.commands) == 2)
        mixes = []
        for _ in range(130):
            daemon.step()
            mixes.append([s.blender.mix for s in daemon.sessions])
    finally:
        daemon.close()
        client.close()
    mixes = np.array(mixes)
    # 2 s at 60 fps = 120 frames from restyled to pass-through, for both performers (the
    # default 0.5 s would have finished after 30 frames).
    assert np.allclose(mixes[59], 1 - 60 / 120) and np.allclose(mixes[29], 1 - 30 / 120)
    assert np.all(mixes[118] > 0.008) and np.all(mixes[119] < 1e-9) and np.all(mixes[125] == 0.0)
    assert daemon.settings.crossfade_frames == 120


def test_the_command_table_is_the_one_both_sides_use():
    from stylecast.daemon.commands import BY_NAME, COMMANDS, parse_command

    assert parse_command("/stylecast/crossfade", "f", (2.0,)) == ("crossfade", 2.0, None)
    assert parse_command("/stylecast/crossfade", "f", (61.0,)) == (None, "bad_arguments")
    assert parse_command("/stylecast/intensity", "fs", (0.5, "bob")) == ("intensity", 0.5, "bob")
    assert parse_command("/stylecast/calibrate", "s", ("bob",)) == ("calibrate", None, "bob")
    assert parse_command("/stylecast/nope", "", ()) == (None, "unknown_address")
    assert set(BY_NAME) == {a.rsplit("/", 1)[1] for a in COMMANDS} and all(COMMANDS[c.address] is c for c in BY_NAME.values())
    frames = []
    daemon = make_daemon(frames)
    try:
        with __import__("pytest").raises(Exception, match="no tracker source to calibrate"):
            daemon.apply("calibrate", None)
        with __import__("pytest").raises(Exception, match="unknown control command"):
            daemon.apply("louder", 1.0)
    finally:
        daemon.close()
