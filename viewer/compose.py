"""One frame's content from the performer table: capsule rows and overlay lines (no GL)."""

from __future__ import annotations

import numpy as np

from .layout import COLOURS, Placement
from .performers import Performer
from .posing import BoneLayout, capsules, pose_world
from .scene import INSTANCE_FLOATS, Capsules

TEXT_COLOUR = (0.92, 0.93, 0.95, 1.0)
DIM_COLOUR = (0.65, 0.67, 0.7, 1.0)


class CapsuleBuilder:
    """Caches a BoneLayout per skeleton and batches FK over performers sharing one."""

    def __init__(self) -> None:
        self._layouts: dict[int, tuple[object, BoneLayout]] = {}

    def layout(self, skeleton) -> BoneLayout:
        if len(self._layouts) > 256:  # skeletons of performers long gone
            self._layouts.clear()
        cached = self._layouts.get(id(skeleton))
        if cached is None or cached[0] is not skeleton:  # id() reuse after garbage collection
            cached = self._layouts[id(skeleton)] = (skeleton, BoneLayout.for_skeleton(skeleton))
        return cached[1]

    def build(self, performers: list[Performer], placements: list[Placement]) -> Capsules:
        groups: dict[int, list[int]] = {}
        for i, p in enumerate(performers):
            groups.setdefault(id(p.skeleton), []).append(i)
        opaque, shells, shadows, extents = [], [], [], []
        for members in groups.values():
            skeleton = performers[members[0]].skeleton
            layout = self.layout(skeleton)
            positions, world = pose_world(skeleton, np.stack([performers[i].root for i in members]),
                                          np.stack([performers[i].rotations for i in members]))
            a, b, radius = capsules(layout, positions, world)
            for k, i in enumerate(members):
                place = placements[i]
                rows = np.empty((layout.count, INSTANCE_FLOATS), np.float32)
                rows[:, 0:3] = a[k] + place.offset
                rows[:, 3:6] = b[k] + place.offset
                rows[:, 6] = radius
                rows[:, 7:11] = place.colour
                (shells if place.translucent else opaque).append(rows)
                ends = rows[:, 0:6].reshape(-1, 3)
                extents.append((performers[i].slot, ends.min(axis=0), ends.max(axis=0), positions[k, 0] + place.offset))
                if not place.translucent:
                    shadows.append(positions[k, 0] * (1, 0, 1) + place.offset)

        def stack(parts):
            return np.concatenate(parts) if parts else np.zeros((0, INSTANCE_FLOATS), np.float32)
        return Capsules(stack(opaque), stack(shells), np.array(shadows, np.float32).reshape(-1, 3), extents)


def overlay_lines(performers: list[Performer], now: float, fps: float, listening: str,
                  ignored: dict[str, int], layout: str, status=None) -> list[tuple[str, tuple]]:
    """The text overlay: renderer fps, the daemon's style (when it answers status requests),
    one line per performer, then what was ignored."""
    lines = [(f"stylecast view  {fps:5.1f} fps  layout {layout}", TEXT_COLOUR),
             (f"listening {listening}", DIM_COLOUR)]
    if status is not None:
        lines.append((f"daemon: style {status.style}  model {status.model}", TEXT_COLOUR))
    if not performers:
        lines.append(("waiting for VMC frames ...", DIM_COLOUR))
    width = max((len(p.label) for p in performers), default=0)
    for p in performers:
        colour = (*COLOURS.get(p.role, (1, 1, 1)), 1.0)
        text = f"{p.slot + 1} {p.role:<8} {p.label:<{width}}  {p.rate(now):5.1f} Hz"
        latency = p.latency()
        if latency is not None:
            text += f"  {latency[0]} {latency[1] * 1e3:5.1f} ms"
        if status is not None and p.role == "restyled" and p.slot < len(status.performers):
            s = status.performers[p.slot]
            text += f"  restyle p50 {s.p50_ms:.0f} p99 {s.p99_ms:.0f} ms  " + (
                "bypass" if s.bypass else f"intensity {s.intensity:.2f}") + (f"  style {s.style}" if s.style else "")
        lines.append((text, colour))
    if any(ignored.values()):
        detail = ", ".join(f"{n} {reason}" for reason, n in sorted(ignored.items()) if n)
        lines.append((f"ignored: {detail}", DIM_COLOUR))
    return lines
