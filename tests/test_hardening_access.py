"""Who may talk to the daemon (issue 7, part 4); docs/THREAT_MODEL.md says why.

* With default options every socket the daemon owns is bound to 127.0.0.1: its VMC input,
  its control port and its VMC senders (which the kernel would otherwise bind to
  0.0.0.0 on the first send). Read from the kernel's own table (/proc/net/udp), not from
  the objects' idea of themselves. An address the user names is honoured.
* The control port refuses senders outside the allow-list: each refusal is counted, each
  refused address logged once, the log and the memory spent on refused addresses are
  bounded however many addresses a flood spoofs.
(test_daemon_control.py already shows one refused sender counted and logged once.)
"""

from __future__ import annotations

import ipaddress
import logging
import os
import re
import socket
import sys

import pytest

from stylecast.motion.clock import FakeClock
from stylecast.daemon.config import DaemonConfig, build_config
from stylecast.daemon.control import ControlServer
from stylecast.motion.errors import UserError
from stylecast.daemon.engine import Daemon
from stylecast.daemon.restylers import IdentityRestyler
from stylecast.drivers.vmc.osc_packets import encode_message
from stylecast.drivers.sources import open_source

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/net/udp")


def _socket_inodes() -> set[int]:
    out = set()
    for fd in os.listdir("/proc/self/fd"):
        try:
            target = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            out.add(int(target[8:-1]))
    return out


def _udp_table() -> dict[int, tuple[str, int]]:
    """inode -> (local address, port) for every UDP socket, from the kernel."""
    table = {}
    for name, family in (("/proc/net/udp", 4), ("/proc/net/udp6", 6)):
        try:
            lines = open(name).read().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            addr_hex, port_hex = fields[1].split(":")
            raw = bytes.fromhex(addr_hex)
            if family == 4:
                ip = str(ipaddress.IPv4Address(raw[::-1]))
            else:  # four little-endian 32-bit words
                ip = str(ipaddress.IPv6Address(b"".join(raw[i:i + 4][::-1] for i in range(0, 16, 4))))
            table[int(fields[9])] = (ip, int(port_hex, 16))
    return table


def _daemon_sockets(daemon_factory):
    before = _socket_inodes()
    daemon = daemon_factory()
    try:
        daemon.start()
        for _ in range(30):  # senders bind on their first datagram
            daemon.step()
        table = _udp_table()
        mine = {table[i] for i in _socket_inodes() - before if i in table}
    finally:
        daemon.close()
    return mine


def test_with_default_options_every_daemon_socket_is_bound_to_loopback():
    defaults = DaemonConfig()
    host, _port = defaults.control_address()
    assert host == "127.0.0.1"
    # Defaults throughout, except the control port number: 0 (any free port) rather than
    # 39570, so this test cannot collide with a daemon someone is running on this machine.
    cfg = build_config({}, {"source": ["vmc://:0"], "out": ["vmc://127.0.0.1:39999"]})
    cfg.control = f"{host}:0"

    # (the vmc:// source idles, so a replay feeds the output)
    from stylecast.drivers.bvh.bvh_replay import ReplaySource

    from .test_daemon import walk_clip

    def make_with_output():
        sources = [ReplaySource(walk_clip(60), "r0", loop=True)] + [open_source(url, f"p{k}") for k, url in
                                                                    enumerate(cfg.source)]
        return Daemon(cfg, sources, IdentityRestyler(), FakeClock(), log_status=False)

    sockets = _daemon_sockets(make_with_output)
    # the VMC input, the control port, the VMC sender (one socket for both performers)
    assert len(sockets) == 3, sockets
    assert {ip for ip, _ in sockets} == {"127.0.0.1"}, sockets
    assert all(port > 0 for _, port in sockets)


def test_an_address_the_user_names_is_honoured():
    from stylecast.drivers.bvh.bvh_replay import ReplaySource

    from .test_daemon import walk_clip

    cfg = DaemonConfig(control="0.0.0.0:0", out=["vmc://127.0.0.1:39999"])

    def make():
        return Daemon(cfg, [ReplaySource(walk_clip(60), "r0", loop=True), open_source("vmc://0.0.0.0:0", "p1")],
                      IdentityRestyler(), FakeClock(), log_status=False)

    sockets = _daemon_sockets(make)
    assert sorted(ip for ip, _ in sockets) == ["0.0.0.0", "0.0.0.0", "127.0.0.1"]  # control, input; sender


def _osc(address, *args):
    return encode_message(address, *args)


def test_refused_senders_are_each_counted_logged_once_and_bounded(caplog):
    caplog.set_level(logging.WARNING, logger="stylecast.daemon")
    server = ControlServer("127.0.0.1", 0, allow=["127.0.0.1"])
    clients = []
    try:
        # 80 real loopback senders that are not 127.0.0.1 (Linux routes all of 127/8 to lo).
        for k in range(2, 82):
            c = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            c.bind((f"127.0.0.{k}", 0))
            clients.append(c)
        for _ in range(3):
            for c in clients:
                c.sendto(_osc("/stylecast/bypass", 1), server.address)
        ok = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        ok.bind(("127.0.0.1", 0))
        clients.append(ok)
        ok.sendto(_osc("/stylecast/intensity", 0.5), server.address)
        import time

        end = time.monotonic() + 20
        while time.monotonic() < end and server.counts["datagrams"] < 241:
            time.sleep(0.01)
        assert server.refused == 240 and server.counts["accepted"] == 1
        assert [c[:2] for c in server.drain()] == [("intensity", 0.5)]  # only the allowed sender
        # A flood from spoofed addresses (fed as the socket thread would): memory and log bounded.
        for k in range(20_000):
            server.handle(_osc("/stylecast/bypass", 1), (str(ipaddress.IPv4Address(0x0A000000 + k)), 9))
        assert server.refused == 20_240
        assert len(server._allowed_cache) <= 4096 and len(server._refused_logged) <= 64
    finally:
        server.close()
        for c in clients:
            c.close()
    refusals = [r for r in caplog.records if "not in the allow-list" in r.getMessage()]
    assert len(refusals) == 64  # the first 64 addresses, once each; then silence, but counted
    assert len({r.getMessage() for r in refusals}) == 64


@pytest.mark.parametrize("host, allowed", [
    ("127.0.0.1", True), ("127.9.9.9", True), ("::1", True), ("::ffff:127.0.0.1", True),
    ("::ffff:10.0.0.1", False), ("10.0.0.1", False), ("fe80::1%eth0", False), ("::", False),
    ("not-an-address", False), ("", False), ("127.0.0.1\x00", False),
])
def test_the_allow_list_reads_every_form_of_sender_address(host, allowed):
    server = ControlServer("127.0.0.1", 0)  # default allow-list: loopback only
    try:
        server.handle(_osc("/stylecast/intensity", 0.5), (host, 1234, 0, 0) if ":" in host else (host, 1234))
        assert server.counts["accepted"] == (1 if allowed else 0)
        assert server.refused == (0 if allowed else 1)
    finally:
        server.close()


def test_the_control_port_replies_only_to_who_asked():
    """A status request is answered to its sender's address, at most a few per tick, so a
    spoofed request cannot turn the daemon into an amplifier towards a third party beyond
    that bound (and spoofing needs an address on the allow-list)."""
    from stylecast.daemon.engine import STATUS_REPLIES_PER_TICK
    from stylecast.drivers.bvh.bvh_replay import ReplaySource

    from .test_daemon import walk_clip

    daemon = Daemon(DaemonConfig(control="127.0.0.1:0"), [ReplaySource(walk_clip(60), "r0", loop=True)],
                    IdentityRestyler(), FakeClock(), log_status=False)
    victim = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    victim.bind(("127.0.0.1", 0))
    victim.setblocking(False)
    try:
        daemon.start()
        for _ in range(500):
            daemon.control.handle(_osc("/stylecast/status"), victim.getsockname())
        for _ in range(3):
            daemon.step()
        replies = 0
        while True:
            try:
                victim.recv(65536)
                replies += 1
            except BlockingIOError:
                break
    finally:
        daemon.close()
        victim.close()
    assert replies == STATUS_REPLIES_PER_TICK  # one datagram per reply; the other requests dropped


@pytest.mark.parametrize("flags, refusal", [
    ({"source": ["vmc://127.0.0.1:39540"], "out": ["vmc://127.0.0.1:39540"]},
     "--out vmc://127.0.0.1:39540 sends to the port of --source vmc://127.0.0.1:39540, so the daemon would read back "
     "what it sends"),
    ({"source": ["vmc://0.0.0.0:39540"], "out": ["vrchat://localhost:39540"]},
     "--out vrchat://localhost:39540 sends to the port of --source vmc://0.0.0.0:39540"),
    ({"source": ["vmc://127.0.0.1:39540", "vmc://localhost:39540"], "out": ["vmc://127.0.0.1:39539"]},
     "--source vmc://localhost:39540 listens on the port of --source vmc://127.0.0.1:39540"),
    ({"source": ["vmc://127.0.0.1:39570"], "out": ["vmc://127.0.0.1:39539"]},
     "--source vmc://127.0.0.1:39570 listens on the port of --control 127.0.0.1:39570"),
    ({"source": ["vmc://127.0.0.1:39540"], "out": ["vmc://127.0.0.1:39539"], "out_input": ["vmc://127.0.0.1:39570"]},
     "--out-input vmc://127.0.0.1:39570 sends to the port of --control 127.0.0.1:39570")])
def test_a_listening_port_named_twice_or_sent_to_is_one_sentence_before_any_socket(flags, refusal):
    # The daemon would read back what it sends, or the second bind would fail only after
    # the first performer had started.
    with pytest.raises(UserError, match=re.escape(refusal)):
        build_config({}, flags)


def test_ports_the_system_picks_and_other_machines_ports_are_not_taken_for_a_clash():
    build_config({}, {"source": ["vmc://127.0.0.1:0", "vmc://127.0.0.1:0"], "out": ["vmc://127.0.0.1:0"],
                      "control": "127.0.0.1:0"})
    build_config({}, {"source": ["vmc://127.0.0.1:39540"], "out": ["vmc://192.168.1.20:39540"]})
