"""Pose sources: the interface the daemon pulls frames from, and the URL registry.

A source is something you *pull* humanoid pose frames from (aiortc's MediaStreamTrack
idea): the daemon's output clock calls ``poll(now)`` once per tick and gets every frame
that has arrived by ``now``, oldest first. A source never calls into the daemon and
never blocks, so one stalled source cannot hold up the others; live sources receive on
their own thread and ``poll`` drains a queue, replay sources compute from the clock.

The contract (aiortc's habit: timestamps travel with the data):

* frames are ``PoseFrame``s of the canonical humanoid (``motion.humanoid.HUMANOID_BONES``,
  T-pose-relative local rotations, root position in cm, internal BVH space), stamped with
  the source's OWN time (a sender's /VMC/Ext/T, a tracker's device clock, a replay's
  timeline), at the source's own rate, oldest first. A driver never resamples and never
  stamps the daemon's time: the session maps source time onto the output clock and
  resamples every stream to ``motion.clock.OUTPUT_FPS`` (``motion.resample.StreamResampler``);
* ``skeleton`` is the performer's humanoid with its own bone offsets, or None until known.
  A source that learns or changes it (a VMC sender's bone offsets, a tracker calibration)
  sets a new ``Skeleton`` object; the session sees the change after a poll and the
  daemon passes it on to the sinks, which then send the performer's proportions.

The registry maps a URL scheme to ``module:function`` and imports it only when a URL
with that scheme is opened, so ``stylecast --help`` never loads a driver and a driver
that is not installed only matters to whoever asks for it. A factory has the signature
``factory(url: EndpointUrl, performer: str) -> Source``.
"""

from __future__ import annotations

import importlib

from stylecast.motion.clip import PoseFrame
from stylecast.motion.errors import UserError
from stylecast.motion.skeleton import Skeleton

from stylecast.drivers.urls import EndpointUrl, parse_url


class Source:
    """Interface (and no-op defaults) of a pose source."""

    performer: str = ""
    skeleton: Skeleton | None = None  # humanoid with this performer's bone lengths, if known

    def start(self, now: float) -> None:
        """Called once, from the daemon's clock, before the first poll."""

    def poll(self, now: float) -> list[PoseFrame]:
        raise NotImplementedError

    @property
    def finished(self) -> bool:
        """True when no frame will ever come again (a replay that does not loop)."""
        return False

    def counters(self) -> dict:
        """Figures for the status line (frames received, rejects, ...)."""
        return {}

    def close(self) -> None:
        """Release sockets, ports and threads; safe to call twice."""


# scheme -> (module, function, what the user should know when it is missing)
SOURCE_SCHEMES: dict[str, tuple[str, str]] = {
    "bvh": ("stylecast.drivers.bvh.bvh_replay", "open_source"),
    # Live drivers written elsewhere (VMC receiver, serial trackers + solver): the daemon
    # only needs a factory with the signature above in these modules.
    "vmc": ("stylecast.drivers.vmc.vmc_in", "open_source"),
    "serial": ("stylecast.drivers.serial.serial_trackers", "open_source"),
}


def source_schemes() -> list[str]:
    return sorted(SOURCE_SCHEMES)


def open_source(url: str | EndpointUrl, performer: str) -> Source:
    """Open the source named by ``url`` for ``performer``; unknown schemes refused."""
    parsed = url if isinstance(url, EndpointUrl) else parse_url(url)
    entry = SOURCE_SCHEMES.get(parsed.scheme)
    if entry is None:
        raise UserError(f"{parsed.text}: unknown source scheme {parsed.scheme!r}; use one of "
                        f"{', '.join(s + '://' for s in source_schemes())}")
    module_name, function = entry
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name != module_name:
            raise
        module = None
    factory = getattr(module, function, None)
    if factory is None:
        raise UserError(f"{parsed.text}: {parsed.scheme}:// sources are not available in this install "
                        f"({module_name}.{function} is missing)")
    return factory(parsed, performer)
