"""Sinks of one performer: restyled VMC, unrestyled VMC (--out-input), BVH recording.

Sinks are opened by URL scheme through ``drivers.sinks`` (``vmc://`` VMC,
``vrchat://`` VRChat OSC trackers); this module only decides where each performer's
frames go:

* every ``--out SCHEME://HOST:PORT`` is one receiver; performer k (k-th ``--source``)
  goes to PORT + k, because a VMC marionette (or a VRChat) shows exactly one avatar per port;
* ``--record out.bvh`` writes performer 0 to out.bvh and performer k > 0 to out.k.bvh.

A ``tap`` callable, when given, sees every datagram before it is sent (tests capture the
exact bytes for the determinism check; the daemon itself never needs it).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from stylecast.drivers.bvh.bvh_recorder import BvhRecorder
from stylecast.drivers.sinks import check_sink_scheme, default_port, open_sink
from stylecast.drivers.urls import parse_url
from stylecast.motion.errors import UserError


def open_outputs(urls: list[str], k: int, bundled: bool, tap=None) -> list:
    """Performer k's sinks for ``--out`` URLs, each opened by its scheme's registered
    factory (``drivers.sinks``). URLs of one scheme with the same options share one sink
    (one encode per frame, fanned out to every target)."""
    groups: dict[tuple, tuple] = {}
    for text in urls:
        url = parse_url(text)
        check_sink_scheme(url)
        key = (url.scheme, tuple(sorted(url.options.items())))
        host, port = url.address() if url.port is not None else (url.host or "127.0.0.1", default_port(url))
        if not 0 < port <= 65535:
            raise UserError(f"{text}: give the receiver's port, as in {url.scheme}://{host or '127.0.0.1'}:39539")
        first, targets = groups.setdefault(key, (url, []))
        targets.append((host, port))
    return [open_sink(url, performer_targets(targets, k), bundled=bundled, tap=tap)
            for url, targets in groups.values()]


def performer_targets(base: list[tuple[str, int]], k: int) -> list[tuple[str, int]]:
    out = []
    for host, port in base:
        if port + k > 65535:
            raise UserError(f"performer {k + 1} would need VMC port {port + k}; choose a lower base port")
        out.append((host, port + k))
    return out


def emit_frames(performers: list["PerformerSinks"], frames: list, time: float) -> None:
    """Each performer's frame to its sinks, restyled to ``outputs``, the input to ``inputs``,
    then the recorder and the frame taps. Sinks of a kind that sends many frames in one call
    (a ``send_many(rows, time)``, as ``VmcOut``'s: the VMC values of every frame in one pass)
    get all of the tick's frames together; any other sink its own, one by one."""
    by_kind: dict[type, list] = {}
    for sinks, frame in zip(performers, frames):
        for sink in sinks.outputs:
            by_kind.setdefault(type(sink), []).append((sink, frame.root_position, frame.rotations, sinks.offsets))
        for sink in sinks.inputs:
            by_kind.setdefault(type(sink), []).append((sink, frame.input_root, frame.input_rotations, sinks.offsets))
    for kind, rows in by_kind.items():
        send_many = getattr(kind, "send_many", None)
        if send_many is not None:
            send_many(rows, time)
        else:
            for sink, *pose in rows:
                sink.send(*pose, time)
    for sinks, frame in zip(performers, frames):
        if sinks.recorder is not None:
            sinks.recorder.append(frame.root_position, frame.rotations)
        for tap in sinks.frame_taps:
            tap(frame)


def recording_path(path: str | Path, k: int) -> Path:
    path = Path(path)
    if k == 0:
        return path
    name = path.name[:-4] if path.name.lower().endswith(".bvh") else path.name
    return path.with_name(f"{name}.{k}.bvh")


class PerformerSinks:
    """Where one performer's frames go. ``offsets`` are the performer's humanoid bone
    offsets (cm); a source that learns or changes them reports it and the daemon calls
    ``set_offsets``, so every sink sends the performer's own proportions."""

    def __init__(self, offsets: np.ndarray, outputs: list | None = None, inputs: list | None = None,
                 recorder: BvhRecorder | None = None, frame_taps: list | None = None):
        self.offsets = np.asarray(offsets, np.float64)
        self.outputs = list(outputs or [])  # restyled frames: VMC, VRChat trackers, ...
        self.inputs = list(inputs or [])  # the unrestyled input (--out-input)
        self.recorder = recorder
        self.frame_taps = list(frame_taps or [])

    @property
    def vmc(self):
        """The first restyled VMC sink (benches and tests read its counters)."""
        from stylecast.drivers.vmc.vmc_out import VmcOut

        return next((o for o in self.outputs if isinstance(o, VmcOut)), None)

    def set_offsets(self, offsets: np.ndarray) -> None:
        self.offsets = np.asarray(offsets, np.float64)

    def emit(self, frame, time: float) -> None:
        emit_frames([self], [frame], time)

    def close(self) -> None:
        for sink in (*self.outputs, *self.inputs, self.recorder):
            if sink is not None:
                sink.close()
