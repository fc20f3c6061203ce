"""Sinks of one performer: restyled VMC, unrestyled VMC (--out-input), BVH recording.

VMC goes through ``drivers.vmc_out`` (the struct-packed encoder and the non-blocking
fan-out sender); this module only decides where each performer's frames go:

* every ``--out vmc://HOST:PORT`` is one receiver; performer k (k-th ``--source``) goes
  to PORT + k, because a VMC marionette shows exactly one avatar per port;
* ``--record out.bvh`` writes performer 0 to out.bvh and performer k > 0 to out.k.bvh.

A ``tap`` callable, when given, sees every datagram before it is sent (tests capture the
exact bytes for the determinism check; the daemon itself never needs it).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from stylecast.drivers.bvh_recorder import BvhRecorder
from stylecast.drivers.osc_packets import parse_vmc_url
from stylecast.drivers.vmc_out import VmcSender
from stylecast.motion.errors import UserError


def parse_outputs(urls: list[str]) -> tuple[list[tuple[str, int]], bool | None]:
    """``vmc://HOST:PORT[?bundled=0|1]`` each -> base addresses and the bundling choice."""
    targets, bundled = [], None
    for url in urls:
        if not url.lower().startswith("vmc://"):
            raise UserError(f"{url}: unknown output scheme; outputs are vmc://HOST:PORT")
        host, port, opts = parse_vmc_url(url, allowed_options=("bundled",))
        if not 0 < port <= 65535:
            raise UserError(f"{url}: give the receiver's port, as in vmc://{host}:39539")
        if "bundled" in opts:
            if opts["bundled"] not in ("0", "1"):
                raise UserError(f"{url}: bundled must be 0 or 1")
            bundled = opts["bundled"] == "1"
        targets.append((host, port))
    return targets, bundled


def performer_targets(base: list[tuple[str, int]], k: int) -> list[tuple[str, int]]:
    out = []
    for host, port in base:
        if port + k > 65535:
            raise UserError(f"performer {k + 1} would need VMC port {port + k}; choose a lower base port")
        out.append((host, port + k))
    return out


def recording_path(path: str | Path, k: int) -> Path:
    path = Path(path)
    if k == 0:
        return path
    name = path.name[:-4] if path.name.lower().endswith(".bvh") else path.name
    return path.with_name(f"{name}.{k}.bvh")


class VmcOut:
    """One performer's VMC stream to one or more receivers."""

    def __init__(self, targets: list[tuple[str, int]], bundled: bool = True, tap=None):
        self.sender = VmcSender(targets, bundled=bundled)
        self.tap = tap

    def send(self, root_position: np.ndarray, rotations: np.ndarray, offsets: np.ndarray, time: float) -> None:
        s = self.sender
        try:
            datagrams = s.encoder.encode(root_position, rotations, offsets, time)
        except ValueError:
            s.frames_rejected += 1  # non-finite pose: never put NaN on the wire
            return
        s.frames_sent += 1
        if self.tap is not None:
            self.tap(datagrams)
        s.send_datagrams(datagrams)

    def counters(self) -> dict:
        return self.sender.counters()

    def close(self) -> None:
        self.sender.close()


class PerformerSinks:
    def __init__(self, offsets: np.ndarray, vmc: VmcOut | None = None, vmc_input: VmcOut | None = None,
                 recorder: BvhRecorder | None = None, frame_taps: list | None = None):
        self.offsets = np.asarray(offsets, np.float64)  # humanoid bone offsets, cm
        self.vmc = vmc
        self.vmc_input = vmc_input
        self.recorder = recorder
        self.frame_taps = list(frame_taps or [])

    def emit(self, frame, time: float) -> None:
        if self.vmc is not None:
            self.vmc.send(frame.root_position, frame.rotations, self.offsets, time)
        if self.vmc_input is not None:
            self.vmc_input.send(frame.root_position, frame.input_rotations, self.offsets, time)
        if self.recorder is not None:
            self.recorder.append(frame.root_position, frame.rotations)
        for tap in self.frame_taps:
            tap(frame)

    def close(self) -> None:
        for sink in (self.vmc, self.vmc_input, self.recorder):
            if sink is not None:
                sink.close()
