"""Pose frames and clips: local rotations as quaternion arrays plus the root's path."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import rotations as rot
from .skeleton import Skeleton


@dataclass(frozen=True, eq=False)
class PoseFrame:
    """One pose of one performer, as it travels through the daemon."""

    performer: str
    timestamp: float  # seconds on the source's clock
    root_position: np.ndarray  # (3,)
    rotations: np.ndarray  # (J, 4) local quaternions (x, y, z, w)


@dataclass(frozen=True, eq=False)
class Clip:
    """A motion: ``rotations`` (T, J, 4) local quaternions, ``root_positions`` (T, 3).

    ``translations`` (T, J, 3), when present, holds per-frame local translations of files
    that animate position channels on non-root joints (the Bandai files do); otherwise
    every non-root joint sits at its skeleton offset.
    """

    skeleton: Skeleton
    rotations: np.ndarray
    root_positions: np.ndarray
    fps: float
    translations: np.ndarray | None = None

    def __post_init__(self) -> None:
        T, J = self.rotations.shape[:2]
        if self.rotations.shape != (T, J, 4) or J != len(self.skeleton):
            raise ValueError(f"rotations must be (T, {len(self.skeleton)}, 4), got {self.rotations.shape}")
        if self.root_positions.shape != (T, 3):
            raise ValueError(f"root_positions must be ({T}, 3), got {self.root_positions.shape}")
        if self.translations is not None and self.translations.shape != (T, J, 3):
            raise ValueError(f"translations must be ({T}, {J}, 3), got {self.translations.shape}")
        if not self.fps > 0:
            raise ValueError(f"frame rate must be positive, got {self.fps}")

    @property
    def num_frames(self) -> int:
        return int(self.rotations.shape[0])

    @property
    def duration(self) -> float:
        return self.num_frames / self.fps

    def local_translations(self) -> np.ndarray:
        """(T, J, 3) local translation of every joint, the root's being its position."""
        if self.translations is not None:
            t = np.array(self.translations, copy=True)
        else:
            t = np.broadcast_to(self.skeleton.offsets, (self.num_frames, len(self.skeleton), 3)).copy()
        t[:, 0] = self.root_positions
        return t

    def frame(self, t: int, performer: str = "") -> PoseFrame:
        return PoseFrame(performer, t / self.fps, self.root_positions[t], self.rotations[t])

    def slice(self, start: int, stop: int) -> "Clip":
        tr = None if self.translations is None else self.translations[start:stop]
        return Clip(self.skeleton, self.rotations[start:stop], self.root_positions[start:stop], self.fps, tr)

    def replace(self, **changes) -> "Clip":
        fields = dict(skeleton=self.skeleton, rotations=self.rotations, root_positions=self.root_positions,
                      fps=self.fps, translations=self.translations)
        fields.update(changes)
        return Clip(**fields)


def forward_kinematics(clip: Clip) -> tuple[np.ndarray, np.ndarray]:
    """World positions (T, J, 3) and world rotations (T, J, 4), vectorised over frames."""
    sk = clip.skeleton
    T, J = clip.num_frames, len(sk)
    local_t = clip.local_translations()
    world_r = np.empty((T, J, 4))
    world_p = np.empty((T, J, 3))
    # One pass over joints in topological order; each step is vectorised over all frames.
    for j, p in enumerate(sk.parents):
        if p < 0:
            world_r[:, j] = clip.rotations[:, j]
            world_p[:, j] = local_t[:, j]
        else:
            world_r[:, j] = rot.multiply(world_r[:, p], clip.rotations[:, j])
            world_p[:, j] = world_p[:, p] + rot.apply(world_r[:, p], local_t[:, j])
    return world_p, world_r


def rest_positions(skeleton: Skeleton) -> np.ndarray:
    """World positions (J, 3) of the rest pose (every rotation identity)."""
    p = np.zeros((len(skeleton), 3))
    for j, parent in enumerate(skeleton.parents):
        if parent >= 0:
            p[j] = p[parent] + skeleton.offsets[j]
    return p


def pose_world(parents: tuple[int, ...], offsets: np.ndarray, root_position: np.ndarray,
               rotations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics of poses (..., J, 4) with the root at ``root_position`` (..., 3)
    and every other joint at its bone offset: world positions (..., J, 3) and world
    rotations (..., J, 4). What a sink needs from a streamed humanoid frame."""
    rotations = np.asarray(rotations, dtype=np.float64)
    offsets = np.asarray(offsets, dtype=np.float64)
    world_r = np.empty_like(rotations)
    world_p = np.empty(rotations.shape[:-1] + (3,))
    for j, p in enumerate(parents):
        if p < 0:
            world_r[..., j, :] = rotations[..., j, :]
            world_p[..., j, :] = root_position
        else:
            world_r[..., j, :] = rot.multiply(world_r[..., p, :], rotations[..., j, :])
            world_p[..., j, :] = world_p[..., p, :] + rot.apply(world_r[..., p, :], offsets[j])
    return world_p, world_r
