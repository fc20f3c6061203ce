"""An orbit camera: yaw and pitch about a target point, at a distance. Metres, Y up.

Matrices are numpy row-major (M @ column vector); ``gl_bytes`` transposes them because
GLSL reads uniforms column-major.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def perspective(fov_y_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    f = 1.0 / np.tan(np.radians(fov_y_deg) / 2)
    return np.array([
        [f / aspect, 0, 0, 0],
        [0, f, 0, 0],
        [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
        [0, 0, -1, 0],
    ], dtype=np.float64)


def look_at(eye: np.ndarray, target: np.ndarray, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    f = np.asarray(target, float) - np.asarray(eye, float)
    f /= np.linalg.norm(f)
    s = np.cross(f, up)
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ np.asarray(eye, float)
    return m


def gl_bytes(m: np.ndarray) -> bytes:
    return np.ascontiguousarray(m.T, dtype=np.float32).tobytes()


@dataclass
class OrbitCamera:
    """Yaw 0 looks at the performer's front (they face +Z), pitch > 0 looks down."""

    target: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.9, 0.0]))
    yaw: float = 20.0  # degrees about +Y
    pitch: float = 12.0  # degrees above the horizon; clamped so the camera never flips
    distance: float = 4.5
    fov: float = 40.0

    MIN_PITCH, MAX_PITCH = -5.0, 85.0
    MIN_DISTANCE, MAX_DISTANCE = 0.5, 60.0

    @property
    def eye(self) -> np.ndarray:
        y, p = np.radians(self.yaw), np.radians(self.pitch)
        offset = np.array([np.sin(y) * np.cos(p), np.sin(p), np.cos(y) * np.cos(p)])
        return self.target + self.distance * offset

    def view(self) -> np.ndarray:
        return look_at(self.eye, self.target)

    def projection(self, aspect: float) -> np.ndarray:
        # The far plane follows the distance so zooming out never clips the floor.
        return perspective(self.fov, aspect, 0.05, max(100.0, self.distance * 4))

    def view_projection(self, aspect: float) -> np.ndarray:
        return self.projection(aspect) @ self.view()

    def orbit(self, d_yaw: float, d_pitch: float) -> None:
        self.yaw = (self.yaw + d_yaw) % 360.0
        self.pitch = float(np.clip(self.pitch + d_pitch, self.MIN_PITCH, self.MAX_PITCH))

    def zoom(self, factor: float) -> None:
        self.distance = float(np.clip(self.distance * factor, self.MIN_DISTANCE, self.MAX_DISTANCE))

    def frame(self, points: np.ndarray, aspect: float = 16 / 9, reserve_bottom: float = 0.0,
              margin: float = 0.12) -> None:
        """Aim at the bounding box of ``points`` (N, 3) and back off just enough that every
        corner of it is on screen, inside ``margin`` (a fraction of the half-screen), above
        the bottom ``reserve_bottom`` fraction of the height (the text panel)."""
        pts = np.asarray(points, float).reshape(-1, 3)
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        if len(pts) == 0:
            return
        r = float(np.clip(reserve_bottom, 0.0, 0.5))
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        centre = (lo + hi) / 2
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        self.target = centre
        basis = self.view()[:3, :3]  # rows: camera right, up, backwards (orientation only)
        rel = corners - centre
        right, up, far = rel @ basis[0], rel @ basis[1], -(rel @ basis[2])
        tan_y = np.tan(np.radians(self.fov) / 2)
        tan_x = tan_y * aspect
        bottom, top = -1.0 + 2 * r + margin, 1.0 - margin  # allowed NDC heights

        def shift_range(d: float) -> tuple[float, float]:
            # Moving camera and target down by s puts a corner at NDC y = (up + s) / ((d + far) tan_y).
            depth = (d + far) * tan_y
            return float(np.max(bottom * depth - up)), float(np.min(top * depth - up))

        # Every corner must fit across: d >= |right| / tan_x - far. And some shift s must fit
        # every corner vertically: for each pair (i, j), corner i's lowest allowed s may not
        # exceed corner j's highest; solved for d, pair by pair (8 x 8, one array).
        across = np.abs(right) / ((1 - margin) * tan_x) - far
        pairs = (bottom * far[:, None] - top * far[None, :]) * tan_y + up[None, :] - up[:, None]
        upright = pairs / ((top - bottom) * tan_y)
        distance = max(float(across.max()), float(upright.max()), float(far.max()) + 0.3)  # not inside
        self.distance = float(np.clip(distance, self.MIN_DISTANCE, self.MAX_DISTANCE))
        low, high = shift_range(self.distance)
        self.target = centre - basis[1] * (low + high) / 2
