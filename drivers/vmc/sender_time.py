"""Which clock a VMC performer's frames are timed by: the sender's /VMC/Ext/T while it
advances, else the frames' arrival.

/VMC/Ext/T is an OSC float32. A sender's uptime fits it (VirtualMotionCapture and VSeeFace
send Unity's ``Time.time``: 0.12 ms steps after 20 minutes up), but a large clock does not:
Unix time as a float32 moves in steps of 128 s, so every frame carried the same T. The
session's resampler drops a frame no later than the one before it, so such a performer was
never shown at all, and nothing said why. A sender whose T stays the same over
``STUCK_FRAMES`` frames in a row is timed by arrival from then on, and one warning says so.
"""

from __future__ import annotations

import logging

log = logging.getLogger("stylecast.drivers.vmc")

# Frames in a row carrying the same T before the sender's clock is given up. A frame sent
# twice, or one split over two bundles that each carry T, repeats it once.
STUCK_FRAMES = 3


class SenderTime:
    def __init__(self, performer: str) -> None:
        self.performer = performer
        self.trusted = True  # False once the sender's T has stood still: arrival times from then on
        self._last: float | None = None
        self._repeats = 0

    def stamp(self, sender_time: float | None, arrival: float) -> float:
        """The time to stamp a frame with: its sender's T, or its arrival (``arrival``, the
        receiver's clock) when it has none or its T is not usable."""
        if sender_time is None or not self.trusted:
            return arrival
        self._repeats = self._repeats + 1 if sender_time == self._last else 0
        self._last = sender_time
        if self._repeats < STUCK_FRAMES:
            return sender_time
        self.trusted = False
        log.warning("performer %s: its /VMC/Ext/T stays at %g over %d frames (an OSC float32 cannot hold a "
                    "clock as large as Unix time); timing its frames by their arrival instead, so send "
                    "seconds since the sender started for its own timing", self.performer, sender_time,
                    STUCK_FRAMES + 1)
        return arrival
