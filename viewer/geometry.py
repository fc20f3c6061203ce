"""Meshes the viewer draws, as plain numpy arrays (no GL here, so they are testable alone).

A bone is one instance of a unit capsule: every vertex stores a unit direction and which
end of the bone it belongs to; the vertex shader places it at ``mix(a, b, end) + radius *
basis * direction``. Because the capsule is round about its axis, the arbitrary roll of
the basis the shader builds never shows, so a bone needs only its two end points.
"""

from __future__ import annotations

import numpy as np


def capsule_mesh(segments: int = 12, rings: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """A unit capsule as (vertices (N, 4) = direction xyz + end flag, triangle indices).

    ``rings`` latitude steps per hemisphere. The equator is emitted twice, once per end,
    so the band between the two copies becomes the cylinder with horizontal normals.
    """
    top = np.linspace(0.0, np.pi / 2, rings + 1)  # end 1 (the child end, +Y)
    bottom = np.linspace(np.pi / 2, np.pi, rings + 1)  # end 0 (the parent end, -Y)
    phi = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    rows = [(t, 1.0) for t in top] + [(t, 0.0) for t in bottom]
    verts = np.array([(np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p), end)
                      for t, end in rows for p in phi], dtype=np.float32)
    tris = []
    for r in range(len(rows) - 1):
        for s in range(segments):
            a, b = r * segments + s, r * segments + (s + 1) % segments
            c, d = a + segments, b + segments
            # Wound counter-clockwise seen from outside (checked in tests via normals).
            tris += [(a, b, c), (b, d, c)]
    return verts, np.array(tris, dtype=np.int32)


def grid_lines(half_extent: float = 6.0, step: float = 0.5, major_every: int = 2) -> np.ndarray:
    """Floor grid on y = 0 as GL_LINES vertices (N, 4) = x, y, z, brightness."""
    n = int(round(half_extent / step))
    out = []
    for i in range(-n, n + 1):
        c = i * step
        shade = 0.55 if i % major_every == 0 else 0.3
        if i == 0:
            shade = 0.8  # the axes through the origin stand out, so "where is 0" is obvious
        out += [(c, 0.0, -half_extent, shade), (c, 0.0, half_extent, shade),
                (-half_extent, 0.0, c, shade), (half_extent, 0.0, c, shade)]
    return np.array(out, dtype=np.float32)


def quad_strip() -> np.ndarray:
    """Corners of a unit quad as a 4-vertex triangle strip (text glyphs, panels)."""
    return np.array([(0, 0), (1, 0), (0, 1), (1, 1)], dtype=np.float32)
