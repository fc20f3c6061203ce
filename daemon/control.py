"""The OSC control port: change intensity, bypass, direction, model while live.

The addresses and their arguments are the one table in ``commands.py``; this module is
the transport (socket, allow-list, counters, queue) and never interprets a command.

Who may talk: UDP is unauthenticated, so the port binds to 127.0.0.1 unless told
otherwise and accepts datagrams only from an allow-list of source networks (default
loopback). A refused sender is logged once (per address, bounded) and counted; a command
with wrong arguments is logged with its usage (an unknown address, with the known ones)
at most once per command every 10 s, and counted; every malformed packet is counted by
reason, never logged line by line: a flood must not become a log flood. Decoding uses
the strict, never-raising decoder of ``drivers.vmc.osc_packets``.

This thread only receives, checks and queues; the output loop applies the commands at
the start of its next tick, so a change takes effect on a frame boundary and every
piece of daemon state is touched by one thread only.
"""

from __future__ import annotations

import ipaddress
import logging
import math
import socket
import threading
import time
from collections import Counter, deque

from stylecast.drivers.vmc.osc_packets import decode, encode_message, pack_datagrams
from stylecast.motion.errors import UserError

from .commands import parse_command, usage_line  # parse_command is also re-exported: tests and fuzzers use it here

log = logging.getLogger("stylecast.daemon")

DEFAULT_CONTROL_PORT = 39570
DEFAULT_ALLOW = ("127.0.0.0/8", "::1/128")
MAX_QUEUED = 256  # commands waiting for the next tick; more are dropped (counted)
_LOGGED_REFUSALS = 64
USAGE_LOG_INTERVAL_S = 10.0  # a wrong command's sentence, at most this often per command


def parse_allow(entries) -> list:
    nets = []
    for e in entries:
        try:
            nets.append(ipaddress.ip_network(str(e).strip(), strict=False))
        except ValueError:
            raise UserError(f"control allow-list entry {e!r} is not an IP address or network; "
                            f"write it as 127.0.0.1 or 192.168.1.0/24") from None
    return nets


class ControlServer:
    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_CONTROL_PORT, allow=DEFAULT_ALLOW):
        self.allow = parse_allow(allow)
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self.sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            self.sock.bind((host, port))
        except OSError as exc:
            self.sock.close()
            raise UserError(f"cannot open the control port {host}:{port} ({exc.strerror}); choose another "
                            f"with --control HOST:PORT or disable it with --control off") from None
        self.sock.settimeout(0.2)
        self.address = self.sock.getsockname()[:2]
        self.commands: deque = deque()
        self.counts: Counter = Counter()
        self._refused_logged: set = set()
        self._usage_logged: dict = {}  # wrong commands: a known address (None: any unknown one) -> last logged
        self._allowed_cache: dict = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="stylecast-control", daemon=True)
        self._thread.start()

    def _allowed(self, host: str) -> bool:
        ok = self._allowed_cache.get(host)
        if ok is None:
            try:
                ip = ipaddress.ip_address(host.split("%")[0])
                if ip.version == 6 and ip.ipv4_mapped:
                    ip = ip.ipv4_mapped
                ok = any(ip in net for net in self.allow)
            except ValueError:
                ok = False
            if len(self._allowed_cache) < 4096:  # bounded: spoofed sources must not grow it
                self._allowed_cache[host] = ok
        return ok

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data, addr = self.sock.recvfrom(65536)
            except socket.timeout:
                continue
            except OSError:
                if self._stop.is_set():
                    return
                continue
            self.handle(data, addr)

    def handle(self, data: bytes, addr) -> None:
        """Check and queue one datagram (public so tests can feed bytes without sockets)."""
        self.counts["datagrams"] += 1
        if not self._allowed(addr[0]):
            self.counts["refused"] += 1
            if addr[0] not in self._refused_logged and len(self._refused_logged) < _LOGGED_REFUSALS:
                self._refused_logged.add(addr[0])
                log.warning("control: refused a command from %s, which is not in the allow-list "
                            "(add it with --allow)", addr[0])
            return
        _, messages = decode(data, lambda reason: self.counts.update([f"malformed_{reason}"]))
        for address, tags, args in messages:
            command = parse_command(address, tags, args)
            if command[0] is None:
                self.counts[command[1]] += 1
                self._log_once(address, command[1])
                continue
            if len(self.commands) >= MAX_QUEUED:
                self.counts["queue_full"] += 1
                continue
            self.counts["accepted"] += 1
            self.commands.append((*command, addr))

    def _log_once(self, address: str, reason: str) -> None:
        """A wrong command's sentence: at most one line per command (all unknown addresses
        count as one) every ``USAGE_LOG_INTERVAL_S``, so a flood of junk cannot become a log
        flood (at most one line per command in the table, and one more); the rest are
        only counted (``/stylecast/status``)."""
        key = address if reason == "bad_arguments" else None
        now = time.monotonic()
        if now - self._usage_logged.get(key, -math.inf) >= USAGE_LOG_INTERVAL_S:
            self._usage_logged[key] = now
            log.warning("control: %s (more within %g s are counted, not logged)", usage_line(address, reason),
                        USAGE_LOG_INTERVAL_S)

    def drain(self) -> list:
        out = []
        while self.commands:
            out.append(self.commands.popleft())
        return out

    def reply(self, addr, messages: list[tuple[str, tuple]]) -> None:
        datagrams = pack_datagrams([encode_message(a, *args) for a, args in messages])
        for d in datagrams:
            try:
                self.sock.sendto(d, addr)
            except OSError:
                self.counts["reply_failed"] += 1

    @property
    def refused(self) -> int:
        return self.counts["refused"]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.sock.close()
