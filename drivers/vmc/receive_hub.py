"""One receive thread for every input socket: a selector, bounded work per wake-up.

Before issue 12 every ``vmc://`` source ran its own receive thread. Junk aimed at the
performers' own ports then kept N threads parsing at once, and the output loop got one
GIL turn in N + 1: the clock starved. Here one thread waits on all sockets; each
wake-up serves every ready socket with at most ``per_wake // ready`` datagrams (at least
one), round-robin, so a flooded port cannot crowd out the others, and one wake-up's work
is bounded whatever arrives. After a wake-up that used its whole budget the thread
sleeps ``BREATH_S``: the output loop and the model always get the GIL between rounds,
and what the hub did not read waits in the kernel's buffer (counted there, not here).

A handler is ``handler(limit) -> int``: read at most ``limit`` datagrams and say how
many it read (limit 0: none, only time-based housekeeping such as expiring stale frames). Handlers of sockets that had
nothing to read are still called with 0 every ``HOUSEKEEPING_S``.
"""

from __future__ import annotations

import selectors
import socket
import threading
import time

PER_WAKE = 512  # datagrams one wake-up reads, shared by the ready sockets
BREATH_S = 0.0005  # pause after a wake-up that used its whole budget (a flood)
HOUSEKEEPING_S = 0.05
SELECT_TIMEOUT_S = 0.05


class ReceiveHub:
    def __init__(self, per_wake: int = PER_WAKE, name: str = "stylecast-receive"):
        self.per_wake = per_wake
        self.name = name
        self._sel = selectors.DefaultSelector()
        self._lock = threading.Lock()
        self._handlers: dict[int, tuple[socket.socket, callable]] = {}
        self._wake_r, self._wake_w = socket.socketpair()  # pokes the selector on changes
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._sel.register(self._wake_r, selectors.EVENT_READ, None)
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self.wakeups = 0
        self.full_wakeups = 0  # wake-ups where a socket used its whole share (a flood)

    def register(self, sock: socket.socket, handler) -> None:
        with self._lock:
            self._handlers[sock.fileno()] = (sock, handler)
            self._sel.register(sock, selectors.EVENT_READ, handler)
            if self._thread is None:
                self._stop.clear()
                self._thread = threading.Thread(target=self._run, name=self.name, daemon=True)
                self._thread.start()
        self._poke()

    def unregister(self, sock: socket.socket) -> None:
        """Stop serving ``sock``; once this returns its handler is not running and will not
        run again. The thread ends with the last socket."""
        thread = None
        with self._lock:
            if self._handlers.pop(sock.fileno(), None) is None:
                return
            self._sel.unregister(sock)
            if not self._handlers:
                thread, self._thread = self._thread, None
                self._stop.set()
        self._poke()
        if thread is not None and thread is not threading.current_thread():
            thread.join()

    @property
    def sockets(self) -> int:
        return len(self._handlers)

    @property
    def thread(self) -> threading.Thread | None:
        return self._thread

    def _poke(self) -> None:
        try:
            self._wake_w.send(b"\0")
        except (BlockingIOError, OSError):
            pass  # already poked (buffer full) or closing: the selector wakes anyway

    def _run(self) -> None:
        last_housekeeping = time.monotonic()
        while not self._stop.is_set():
            events = self._sel.select(SELECT_TIMEOUT_S)
            # The lock is held for the whole round, so unregister() cannot return while a
            # handler of its socket runs (its caller then closes the socket).
            with self._lock:
                if self._stop.is_set():
                    return
                ready = [key for key, _ in events if key.data is not None and key.fd in self._handlers]
                if any(key.data is None for key, _ in events):
                    self._drain_pokes()
                flooded = False
                if ready:
                    self.wakeups += 1
                    share = max(1, self.per_wake // len(ready))
                    for key in ready:
                        flooded |= (key.data(share) or 0) >= share
                now = time.monotonic()
                if now - last_housekeeping >= HOUSEKEEPING_S:
                    last_housekeeping = now
                    served = {key.fd for key in ready}
                    for fd, (_, handler) in list(self._handlers.items()):
                        if fd not in served:
                            handler(0)
            if flooded:
                self.full_wakeups += 1
                time.sleep(BREATH_S)

    def _drain_pokes(self) -> None:
        try:
            while self._wake_r.recv(4096):
                pass
        except (BlockingIOError, OSError):
            pass


_shared: ReceiveHub | None = None
_shared_lock = threading.Lock()


def shared_hub() -> ReceiveHub:
    """The process's one receive hub (all ``vmc://`` sources use it)."""
    global _shared
    with _shared_lock:
        if _shared is None:
            _shared = ReceiveHub()
        return _shared
