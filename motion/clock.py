"""Time, in one place: the output rate and the one clock abstraction.

``OUTPUT_FPS`` is the rate of everything stylecast emits (the daemon's output clock,
recordings, the model's words); sources may run at any rate and the daemon resamples
them onto it. Everything that waits or stamps asks an injected ``Clock`` (aiortc's
habit), so tests replay faster than real time and get the same frames, in the same
order, every run; drivers take the same clock from below (the daemon, a test, the
emulator) instead of keeping their own.

* ``RealClock``: ``time.monotonic`` (never jumps with NTP or DST) and a sleep that wakes
  slightly early and spins the last half millisecond, because ``time.sleep`` on a loaded
  Linux box overshoots by up to a millisecond or two and the output clock is 60 Hz.
* ``FakeClock``: time moves only when somebody sleeps; ``sleep_until`` jumps to the
  target. ``virtual = True`` tells the engine that model time is free: it waits for every
  inference result that is due instead of declaring it late, so a fake-clock replay is
  deterministic whatever the machine's speed.
"""

from __future__ import annotations

import threading
import time


OUTPUT_FPS = 60.0  # frames per second of every output stream (and of the model's words)


class Clock:
    """Interface: seconds as a float on an arbitrary, monotonic origin."""

    virtual = False

    def now(self) -> float:
        raise NotImplementedError

    def sleep_until(self, t: float) -> None:
        raise NotImplementedError

    def sleep(self, dt: float) -> None:
        if dt > 0:
            self.sleep_until(self.now() + dt)


class RealClock(Clock):
    SPIN_S = 0.0005

    def __init__(self, stop: threading.Event | None = None):
        # An optional stop event lets Ctrl-C/SIGTERM cut a sleep short.
        self._stop = stop

    def now(self) -> float:
        return time.monotonic()

    def sleep_until(self, t: float) -> None:
        while True:
            left = t - time.monotonic()
            if left <= 0:
                return
            if left > self.SPIN_S:
                if self._stop is not None:
                    if self._stop.wait(left - self.SPIN_S):
                        return
                else:
                    time.sleep(left - self.SPIN_S)
            # else: spin; the remaining sliver is below the scheduler's resolution


class FakeClock(Clock):
    virtual = True

    def __init__(self, start: float = 0.0):
        self._t = float(start)
        self._lock = threading.Lock()

    def now(self) -> float:
        return self._t

    def sleep_until(self, t: float) -> None:
        with self._lock:
            if t > self._t:
                self._t = float(t)

    def advance(self, seconds: float) -> None:
        self.sleep_until(self._t + seconds)
