"""Pelvis height (``PelvisHeight``): the restyle bends knees and tilts the pelvis (an
exhausted stance is lower), but the root passes through, so with the hips at the input's
height the restyled planted feet float above the floor (measured on held-out normal clips
with the shipped model: median 4.4-5.9 cm in standing actions, 2.2-2.5 cm in walks) and
the IK could only put them down by straightening the legs again, undoing the style. So
the root is lowered (or raised) by the gap of the planted foot that floats most: that
foot then reaches its target with the restyled leg bend, the other bends further. The gap
is held through frames with no planted foot (a run's flight) and low-passed (a triple
pole, like the correction filter) so the hips never jump: fast while a foot is always
down, so the hips carry the restyled bend step by step, slower once the body has left the
floor, where each short contact asks for a new gap; it is capped so a wild output cannot
fold the legs. This moves the root, which the paper passes through: only
vertically, only by what the restyled legs themselves ask for.

A style may ask for quicker hips than its lock's (``ContactSettings.pelvis_quick_tau``, in
the share ``pelvis_quick_share`` of the ground low-pass that the style mix sets: the
restyler's ``quick_hips``); the share moves smoothly, so a live change of style never steps
the hips.
"""

from __future__ import annotations

import numpy as np

from ..smoothing import TriplePole


class PelvisHeight:
    """The vertical root offset of the output (see the module docstring), causal, with its
    state carried from block to block: a clip at once and a stream a frame at a time give
    the same offsets.

    Two low-passes of the held gap run side by side: ``tau`` while a foot is always down
    (standing, walking) and ``flight_tau`` once the body has left the floor within the last
    ``flight_memory`` frames (a run, a jump), crossfaded by a weight that is itself
    low-passed over ``flight_tau`` so the switch never steps. Without a ``flight_memory``
    (or with ``flight_tau`` = ``tau``) it is the one low-pass.

    While a foot is down, the share ``quick_share`` (``set_quick_share``) of the ground
    low-pass runs at ``quick_tau`` instead of ``tau``, the share itself low-passed over
    ``tau``. The quick low-pass runs whatever the share, so its state is ready when a style
    turns it on; at share 0 the output is the slow one's to the bit."""

    def __init__(self, tau: float, cap: float, flight_tau: float | None = None, flight_memory: int = 0,
                 quick_tau: float | None = None, quick_share: float = 0.0):
        self.tau, self.cap = float(tau), float(cap)
        self.flight_tau = self.tau if flight_tau is None else float(flight_tau)
        self.flight_memory = int(flight_memory)
        self._ground, self._flight = TriplePole(self.tau), TriplePole(self.flight_tau)
        self._weight = TriplePole(self.flight_tau)  # of the flight low-pass, 0..1
        # The quick share (None: no quick low-pass, the tau is the quick one already).
        self._quick = None if quick_tau is None or float(quick_tau) == self.tau else TriplePole(float(quick_tau))
        self._share = TriplePole(self.tau)
        self.set_quick_share(quick_share)
        self._share.settle_on(self._share_target)  # a stream starts with its style's share
        self._held = 0.0  # the last gap seen with a foot planted
        self._since_flight = self.flight_memory  # frames since the last with no foot planted

    def drops(self, gaps: np.ndarray, planted: np.ndarray) -> np.ndarray:
        """Per frame in order: the output ankles' height over the input's (n, 2) and which
        feet are being locked (n, 2) -> how far to lower the root (n,), negative = raise."""
        if len(gaps) == 1:
            return np.array([self.drop_of_one_frame(gaps[0].tolist(), planted[0].tolist())])
        if self.tau <= 0:
            return np.zeros(len(gaps))
        wanted = np.where(planted, gaps, -np.inf).max(axis=1)
        seen = np.isfinite(wanted)
        # Hold the last planted gap through frames with no foot down.
        last = np.maximum.accumulate(np.where(seen, np.arange(len(gaps)), -1))
        held = np.where(last >= 0, wanted[np.maximum(last, 0)], self._held)
        if seen.any():
            self._held = float(wanted[seen][-1])
        held = np.clip(held, -self.cap, self.cap)
        # Frames since the last one with no foot planted, carried over from the last block.
        index = np.arange(len(gaps))
        since = index - np.maximum.accumulate(np.where(seen, -1 - self._since_flight, index))
        self._since_flight = int(min(since[-1], self.flight_memory))
        weight = self._weight.run((since < self.flight_memory).astype(float))
        ground = self._ground.run(held)
        if self._quick is not None:
            share = self._share.run(np.full(len(gaps), self._share_target))
            ground = (1.0 - share) * ground + share * self._quick.run(held)
        return (1.0 - weight) * ground + weight * self._flight.run(held)

    def drop_of_one_frame(self, gaps: list, planted: list) -> float:
        """``drops`` for one frame on Python floats (the daemon's case): two gaps, two flags."""
        if self.tau <= 0:
            return 0.0
        down = [g for g, p in zip(gaps, planted) if p]
        if down:
            self._held = max(down)
        self._since_flight = min(self._since_flight + 1, self.flight_memory) if down else 0
        x = min(max(self._held, -self.cap), self.cap)
        weight = self._weight.step(float(self._since_flight < self.flight_memory))
        ground = self._ground.step(x)
        if self._quick is not None:
            share = self._share.step(self._share_target)
            ground = (1.0 - share) * ground + share * self._quick.step(x)
        return (1.0 - weight) * ground + weight * self._flight.step(x)

    @property
    def quick_share(self) -> float:
        """The share of the ground low-pass at ``quick_tau`` the hips are moving to."""
        return self._share_target

    def set_quick_share(self, share: float) -> None:
        """The share of the ground low-pass at ``quick_tau`` (a new style mix; 0..1); the
        hips move to it over ``tau``."""
        self._share_target = min(max(float(share), 0.0), 1.0)
