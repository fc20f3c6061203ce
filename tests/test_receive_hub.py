"""One receive thread for all input ports (issue 12): a selector over every socket,
bounded work per wake-up, a flooded port cannot crowd out a quiet one."""

from __future__ import annotations

import socket
import threading
import time

from stylecast.drivers.vmc.receive_hub import ReceiveHub
from stylecast.drivers.vmc.vmc_in import VmcReceiver


def udp_pair():
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    rx.bind(("127.0.0.1", 0))
    rx.setblocking(False)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    return rx, tx


class Reader:
    """A hub handler that reads and records how much each call was allowed and read."""

    def __init__(self, sock):
        self.sock, self.limits, self.read = sock, [], 0

    def __call__(self, limit):
        self.limits.append(limit)
        n = 0
        for _ in range(limit):
            try:
                self.sock.recv(2048)
            except BlockingIOError:
                break
            n += 1
        self.read += n
        return n


def wait_for(condition, seconds=5.0):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.005)
    return False


def test_a_flooded_socket_gets_a_bounded_share_and_a_quiet_one_is_served_at_once():
    flood_rx, flood_tx = udp_pair()
    quiet_rx, quiet_tx = udp_pair()
    for _ in range(3000):  # a backlog far above one wake-up's budget
        flood_tx.sendto(b"junk" * 8, flood_rx.getsockname())
    quiet_tx.sendto(b"frame", quiet_rx.getsockname())
    flood, quiet = Reader(flood_rx), Reader(quiet_rx)
    seen = {}

    def quiet_handler(limit):
        n = quiet(limit)
        if n and "flood_read" not in seen:
            seen["flood_read"] = flood.read
        return n

    hub = ReceiveHub(per_wake=100)
    try:
        hub.register(flood_rx, flood)
        hub.register(quiet_rx, quiet_handler)
        assert wait_for(lambda: "flood_read" in seen)
        # The quiet socket was served while most of the flood still waited in the kernel.
        assert seen["flood_read"] <= 200
        assert max(flood.limits) <= 100  # bounded work per wake-up, whatever is waiting
        assert wait_for(lambda: flood.read == 3000)  # and the backlog is still read, in rounds
        assert hub.full_wakeups > 0
    finally:
        hub.unregister(flood_rx)
        hub.unregister(quiet_rx)
        for s in (flood_rx, flood_tx, quiet_rx, quiet_tx):
            s.close()
    assert hub.thread is None


def test_every_receiver_shares_one_thread_that_ends_with_the_last():
    hub = ReceiveHub()
    before = threading.active_count()
    receivers = [VmcReceiver("127.0.0.1", 0) for _ in range(6)]
    try:
        for r in receivers:
            r.start(hub)
        assert threading.active_count() == before + 1
        assert len({id(r._thread) for r in receivers}) == 1 and receivers[0]._thread.is_alive()
        assert hub.sockets == 6
    finally:
        for r in receivers:
            r.close()
    assert hub.thread is None and threading.active_count() == before


def test_housekeeping_reaches_sockets_that_receive_nothing():
    rx, tx = udp_pair()
    reader = Reader(rx)
    hub = ReceiveHub()
    try:
        hub.register(rx, reader)
        assert wait_for(lambda: reader.limits.count(0) >= 2, 2.0)  # expire() of stale frames runs
    finally:
        hub.unregister(rx)
        rx.close()
        tx.close()
