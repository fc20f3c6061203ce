"""The GL side of a frame: floor grid, blob shadows, instanced bone capsules, overlay text.

One instance buffer holds every capsule of every performer, so the bones of 8 performers
cost two draw calls (opaque, then translucent overlay shells), not 8 x 26.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .camera import OrbitCamera, gl_bytes
from .geometry import capsule_mesh, grid_lines, quad_strip
from .shaders import CAPSULE_FS, CAPSULE_VS, GRID_FS, GRID_VS, SHADOW_FS, SHADOW_VS
from .text import TextOverlay

BACKGROUND = (0.11, 0.12, 0.14)
INSTANCE_FLOATS = 11  # a(3) b(3) radius(1) colour(4)
OVERLAY_INFLATE = 1.25
CAPSULE_DETAIL = {"fine": (12, 4), "coarse": (8, 2)}  # (segments around, rings per hemisphere)
LOD_FINE_PX = 8.0


@dataclass
class Capsules:
    """Capsule rows (N, 11) of one frame: opaque bones, translucent overlay shells, and the
    floor points under each performer's hips for the blob shadows."""

    opaque: np.ndarray
    shells: np.ndarray
    shadow_centres: np.ndarray
    extents: list = field(default_factory=list)  # per performer: (slot, lo, hi, hips) (3,) each, for framing

    @classmethod
    def empty(cls) -> "Capsules":
        z = np.zeros((0, INSTANCE_FLOATS), np.float32)
        return cls(z, z, np.zeros((0, 3), np.float32))

    def bounds(self, slot: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Corner points (2k, 3) and hips positions (k, 3) of the performers in ``slot``
        (all when None)."""
        chosen = [e for e in self.extents if slot is None or e[0] == slot]
        corners = np.array([c for _, lo, hi, _ in chosen for c in (lo, hi)], np.float64).reshape(-1, 3)
        return corners, np.array([e[3] for e in chosen], np.float64).reshape(-1, 3)


class InstancedMesh:
    """Meshes sharing one growing per-instance buffer (levels of detail of one shape).
    GL 3.3 has no base-instance draw, so each group drawn separately (opaque bones,
    shells) gets its own InstancedMesh."""

    def __init__(self, ctx, program, meshes: dict, instance_format: tuple, reserve_rows: int = 256) -> None:
        """``meshes``: name -> (vertex buffer format tuple, index buffer or None)."""
        self.ctx, self.program, self.meshes, self.instance_format = ctx, program, meshes, instance_format
        self.row_bytes = 4 * sum(int(part[:-1] or 1) for part in instance_format[0].replace("/i", "").split())
        self._allocate(reserve_rows * self.row_bytes)

    def _allocate(self, nbytes: int) -> None:
        self.buffer = self.ctx.buffer(reserve=nbytes, dynamic=True)
        self.vaos = {name: self.ctx.vertex_array(self.program, [fmt, (self.buffer, *self.instance_format)],
                                                 index_buffer=ibo)
                     for name, (fmt, ibo) in self.meshes.items()}

    def draw(self, mode, rows: np.ndarray, mesh: str | None = None, vertices: int = -1) -> None:
        if not len(rows):
            return
        data = np.ascontiguousarray(rows, np.float32).tobytes()
        if len(data) > self.buffer.size:
            self.buffer.release()
            for vao in self.vaos.values():
                vao.release()
            self._allocate(len(data) * 2)
        self.buffer.orphan()  # a fresh store: the GL never waits for last frame's draw to finish
        self.buffer.write(data)
        self.vaos[mesh or next(iter(self.vaos))].render(mode, vertices=vertices, instances=len(rows))


def capsule_detail(camera: OrbitCamera, height_px: int) -> str:
    """"fine" when a typical bone (5 cm radius) at the camera's distance is at least
    ``LOD_FINE_PX`` pixels wide in radius, else "coarse". llvmpipe shades vertices on the
    CPU, so the coarse mesh (48 vertices instead of 120) is what lets 8 framed performers
    (small on screen, where the difference cannot be seen) render at 60 fps."""
    focal_px = height_px / 2 / np.tan(np.radians(camera.fov) / 2)
    return "fine" if 0.05 * focal_px / max(camera.distance, 1e-3) >= LOD_FINE_PX else "coarse"


class Scene:
    def __init__(self, ctx, text_size: int = 15) -> None:
        self.ctx = ctx
        self.capsule_prog = ctx.program(vertex_shader=CAPSULE_VS, fragment_shader=CAPSULE_FS)
        meshes = {}
        for name, (segments, rings) in CAPSULE_DETAIL.items():
            verts, tris = capsule_mesh(segments, rings)
            meshes[name] = ((ctx.buffer(verts.tobytes()), "3f 1f", "in_dir", "in_end"), ctx.buffer(tris.tobytes()))
        capsule_rows = ("3f 3f 1f 4f/i", "i_a", "i_b", "i_radius", "i_color")
        self.bones = InstancedMesh(ctx, self.capsule_prog, meshes, capsule_rows)
        self.shells = InstancedMesh(ctx, self.capsule_prog, meshes, capsule_rows)

        self.grid_prog = ctx.program(vertex_shader=GRID_VS, fragment_shader=GRID_FS)
        grid = grid_lines()
        self.grid_vao = ctx.vertex_array(self.grid_prog, [(ctx.buffer(grid.tobytes()), "3f 1f", "in_pos", "in_shade")])

        self.shadow_prog = ctx.program(vertex_shader=SHADOW_VS, fragment_shader=SHADOW_FS)
        corners = (ctx.buffer(quad_strip().tobytes()), "2f", "in_corner")
        self.shadows = InstancedMesh(ctx, self.shadow_prog, {"quad": (corners, None)}, ("3f/i", "i_center"),
                                     reserve_rows=16)
        self.text = TextOverlay(ctx, text_size)

    def render(self, camera: OrbitCamera, size: tuple[int, int], capsules: Capsules,
               lines: list[tuple[str, tuple]]) -> None:
        """Draw into the currently bound framebuffer of ``size`` pixels."""
        ctx = self.ctx
        w, h = size
        ctx.viewport = (0, 0, w, h)
        ctx.clear(*BACKGROUND, 1.0)
        vp = gl_bytes(camera.view_projection(w / max(h, 1)))

        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE)
        ctx.disable(ctx.BLEND)
        self.grid_prog["u_viewproj"].write(vp)
        self.grid_prog["u_center"].value = tuple(float(v) for v in camera.target)
        self.grid_prog["u_background"].value = BACKGROUND
        self.grid_vao.render(ctx.LINES)

        ctx.enable(ctx.BLEND)
        ctx.blend_func = ctx.SRC_ALPHA, ctx.ONE_MINUS_SRC_ALPHA
        self.shadow_prog["u_viewproj"].write(vp)
        self.shadow_prog["u_radius"].value = 0.4
        ctx.depth_mask = False  # blobs must not hide each other or the grid lines
        self.shadows.draw(ctx.TRIANGLE_STRIP, capsules.shadow_centres, vertices=4)
        ctx.depth_mask = True

        self.capsule_prog["u_viewproj"].write(vp)
        self.capsule_prog["u_eye"].value = tuple(float(v) for v in camera.eye)
        ctx.enable(ctx.CULL_FACE)  # closed meshes: back faces are never seen
        ctx.disable(ctx.BLEND)
        self.capsule_prog["u_inflate"].value = 1.0
        detail = capsule_detail(camera, h)
        self.bones.draw(ctx.TRIANGLES, capsules.opaque, detail)
        # Shells after the opaque bones, without writing depth, so they tint what they
        # cover instead of hiding it.
        ctx.enable(ctx.BLEND)
        ctx.depth_mask = False
        self.capsule_prog["u_inflate"].value = OVERLAY_INFLATE
        self.shells.draw(ctx.TRIANGLES, capsules.shells, detail)
        ctx.depth_mask = True
        ctx.disable(ctx.CULL_FACE)
        self.text.draw(lines, size)
        ctx.disable(ctx.BLEND)
