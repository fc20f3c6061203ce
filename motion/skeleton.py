"""The immutable skeleton: joint names, parents, rest offsets and (for BVH) channels."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

ROTATION_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")
POSITION_CHANNELS = ("Xposition", "Yposition", "Zposition")


def _frozen(a, dtype=np.float64) -> np.ndarray:
    a = np.array(a, dtype=dtype, copy=True)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Skeleton:
    """A joint hierarchy in topological order (every parent comes before its children).

    ``offsets[j]`` is joint j's rest translation in its parent's frame (centimetres);
    ``channels[j]`` lists the BVH channels of joint j, which also fixes its Euler order;
    ``end_sites`` maps a joint index to the offset of its BVH End Site.
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...] = ()
    end_sites: tuple[tuple[int, tuple[float, float, float]], ...] = ()
    _index: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        names = tuple(self.names)
        parents = tuple(int(p) for p in self.parents)
        if len(names) != len(parents) or len(set(names)) != len(names):
            raise ValueError("skeleton joint names must be unique and match the parent list")
        if parents and parents[0] != -1:
            raise ValueError("the first joint of a skeleton must be the root (parent -1)")
        for j, p in enumerate(parents[1:], start=1):
            if not 0 <= p < j:
                raise ValueError(f"joint {names[j]!r} must come after its parent")
        offsets = _frozen(self.offsets).reshape(len(names), 3)
        channels = tuple(tuple(c) for c in self.channels) or tuple(
            (POSITION_CHANNELS + ("Zrotation", "Xrotation", "Yrotation")) if p == -1
            else ("Zrotation", "Xrotation", "Yrotation")
            for p in parents
        )
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "channels", channels)
        object.__setattr__(self, "end_sites", tuple((int(j), tuple(map(float, o))) for j, o in self.end_sites))
        object.__setattr__(self, "_index", {n: i for i, n in enumerate(names)})

    def __len__(self) -> int:
        return len(self.names)

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, Skeleton)
            and self.names == other.names
            and self.parents == other.parents
            and self.channels == other.channels
            and np.array_equal(self.offsets, other.offsets)
        )

    __hash__ = None  # type: ignore[assignment]  (arrays inside: compare, don't hash)

    def index(self, name: str) -> int:
        return self._index[name]

    def get(self, name: str) -> int | None:
        return self._index.get(name)

    def children(self, j: int) -> list[int]:
        return [c for c, p in enumerate(self.parents) if p == j]

    def euler_order(self, j: int) -> str:
        """The joint's Euler order from its rotation channels, e.g. "ZXY"."""
        return "".join(c[0] for c in self.channels[j] if c in ROTATION_CHANNELS)

    def has_position_channels(self, j: int) -> bool:
        return any(c in POSITION_CHANNELS for c in self.channels[j])

    def with_offsets(self, offsets: np.ndarray) -> "Skeleton":
        return Skeleton(self.names, self.parents, offsets, self.channels, self.end_sites)
