"""Style, intensity and restyle latency: asked of the daemon over its OSC control port.

The VMC stream carries poses only, so the overlay's daemon figures come from the status
reply the daemon's control port gives any allowed sender (loopback by default):

    -> /stylecast/status
    <- /stylecast/status/daemon     s style, s model, i performers, i ticks, i dropped, i faults, i refused
    <- /stylecast/status/performer  s name, i in, i out, f p50 ms, f p99 ms, i late, i held, i skipped,
                                    i failed words, f intensity, i bypass, i lost, s style mix
                                    (one per performer, in order; daemons before the style mix
                                    send no such argument)

Spoken as OSC, never by importing the daemon. The poller asks once a second; a daemon
that is not there costs one tiny datagram a second and the overlay shows nothing of it.
"""

from __future__ import annotations

import math
import select
import socket
import threading
import time
from dataclasses import dataclass, field

from stylecast.drivers.vmc.osc_packets import decode, encode_message
from stylecast.motion.errors import UserError

REQUEST = encode_message("/stylecast/status")
STALE_AFTER_S = 3.0  # no reply for this long: the daemon is gone, stop showing its figures


@dataclass(frozen=True)
class PerformerStatus:
    name: str
    p50_ms: float
    p99_ms: float
    intensity: float
    bypass: bool
    style: str = ""  # the performer's style mix on a multi-style model ("" = the model's own)


@dataclass(frozen=True)
class DaemonStatus:
    style: str
    model: str
    performers: tuple[PerformerStatus, ...] = field(default_factory=tuple)


def parse_status(messages, previous: DaemonStatus | None = None) -> DaemonStatus | None:
    """Fold decoded messages into a status: a daemon message starts a new one, performer
    messages extend it (a reply may span datagrams). Malformed messages are skipped."""
    status = previous
    for address, tags, args in messages:
        if address == "/stylecast/status/daemon" and tags[:2] == "ss":
            status = DaemonStatus(args[0][:40], args[1][:60])
        elif address == "/stylecast/status/performer" and status is not None and tags[:11] == "siiffiiiifi":
            p50, p99, intensity = args[3], args[4], args[9]
            if all(math.isfinite(v) for v in (p50, p99, intensity)):
                style = args[12][:60] if tags[11:13] == "is" else ""
                perf = PerformerStatus(args[0][:40], p50, p99, intensity, bool(args[10]), style)
                status = DaemonStatus(status.style, status.model, (*status.performers, perf)[:64])
    return status


class StatusPoller:
    """A thread that asks ``host:port`` for status every ``interval`` seconds."""

    def __init__(self, host: str, port: int, interval: float = 1.0, clock=time.monotonic) -> None:
        self.interval, self.clock = interval, clock
        try:
            family, _, _, _, sockaddr = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)[0]
        except (socket.gaierror, UnicodeError):
            raise UserError(f"cannot resolve the daemon's control address {host!r}; give an IP address "
                            f"as in --status 127.0.0.1:39570, or --status off") from None
        self.address = sockaddr[:2]
        self._sock = socket.socket(family, socket.SOCK_DGRAM)
        self._sock.setblocking(False)
        self._latest: tuple[float, DaemonStatus] | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="viewer-status", daemon=True)

    def start(self) -> "StatusPoller":
        self._thread.start()
        return self

    def _run(self) -> None:
        next_ask = 0.0
        pending: DaemonStatus | None = None
        while not self._stop.is_set():
            if self.clock() >= next_ask:
                next_ask = self.clock() + self.interval
                pending = None
                try:
                    self._sock.sendto(REQUEST, self.address)
                except OSError:  # no route, or an ICMP error of the last request: ask again later
                    pass
            select.select([self._sock], [], [], 0.1)
            for _ in range(64):
                try:
                    data, sender = self._sock.recvfrom(65536)
                except OSError:  # nothing left, or "connection refused" from a closed port
                    break
                if sender[:2] != self.address:
                    continue  # only the daemon we asked may set what the overlay says
                _, messages = decode(data, lambda reason: None)
                pending = parse_status(messages, pending)
                if pending is not None:
                    with self._lock:
                        self._latest = (self.clock(), pending)

    def latest(self) -> DaemonStatus | None:
        with self._lock:
            if self._latest is None or self.clock() - self._latest[0] > STALE_AFTER_S:
                return None
            return self._latest[1]

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
        self._sock.close()
