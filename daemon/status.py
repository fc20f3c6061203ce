"""Status figures: latency percentiles, the periodic log line, the OSC status reply.

Latency is measured per output frame from the arrival of input frame t (its timestamp on
the daemon clock) to the moment its restyled frame has been handed to the socket. The
window keeps the last few seconds so p99 tracks the present, not the whole run.
"""

from __future__ import annotations

from collections import deque

import numpy as np

WINDOW_FRAMES = 600  # 10 s at 60 fps


class LatencyWindow:
    def __init__(self, size: int = WINDOW_FRAMES):
        self._values: deque = deque(maxlen=size)

    def add(self, seconds: float) -> None:
        self._values.append(seconds)

    def percentile(self, q: float) -> float:
        if not self._values:
            return 0.0
        return float(np.percentile(np.fromiter(self._values, float, len(self._values)), q))

    def __len__(self) -> int:
        return len(self._values)


def status_line(c: dict, style: str) -> str:
    mode = "bypass" if c["bypass"] else f"intensity {c['intensity']:.2f}"
    lost = " LOST (no input)" if c.get("lost") else ""
    return (f"{c['performer']}{lost}: in {c['frames_in']} out {c['frames_out']} | latency p50 "
            f"{c['latency_p50_ms']:.1f} ms p99 {c['latency_p99_ms']:.1f} ms | late {c['late']} "
            f"held {c['held']} skipped {c['skipped']} dropped {c.get('dropped', 0)} failed-words "
            f"{c['words_failed']} | {style} {mode} (mix {c['mix']:.2f})")


def status_messages(snapshot: dict) -> list[tuple[str, tuple]]:
    """The status as OSC messages (address, args) for a reply datagram.

    /stylecast/status/daemon  s style, s model, i performers, i output frames, i dropped
                              output ticks, i inference faults, i control refusals
    /stylecast/status/performer  s name, i frames in, i frames out, f p50 ms, f p99 ms,
                              i late, i held, i skipped, i failed words, f intensity, i bypass,
                              i lost (1 when no input for a second), s style mix ("" = the
                              model's own)
    """
    d = snapshot["daemon"]
    out = [("/stylecast/status/daemon", (str(d["style"]), str(d["model"]), int(d["performers"]),
                                         int(d["ticks"]), int(d["dropped_ticks"]), int(d["faults"]),
                                         int(d["control_refused"])))]
    for p in snapshot["performers"]:
        out.append(("/stylecast/status/performer", (
            str(p["performer"]), int(p["frames_in"]), int(p["frames_out"]),
            float(p["latency_p50_ms"]), float(p["latency_p99_ms"]), int(p["late"]), int(p["held"]),
            int(p["skipped"]), int(p["words_failed"]), float(p["intensity"]), int(bool(p["bypass"])),
            int(bool(p.get("lost"))), str(p.get("style", "")))))
    return out
