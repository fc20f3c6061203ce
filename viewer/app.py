"""The Viewer: performer table + camera + scene, drivable headless (tests, snapshots,
frame sequences) or from a window's event loop.

Time is injected (``clock``), so a test can feed frames and render "at" any moment.
"""

from __future__ import annotations

import time
from collections import deque
from pathlib import Path

import numpy as np

from stylecast.motion.humanoid import humanoid_skeleton_default

from .camera import OrbitCamera
from .compose import CapsuleBuilder, overlay_lines
from .layout import DEFAULT_SPACING, LAYOUTS, place
from .performers import PerformerTable
from .scene import Capsules, Scene

FOLLOW_SMOOTHING_S = 0.4  # time constant of the camera following its performers
TEXT_REFRESH_S = 0.25


def text_size(size: tuple[int, int]) -> int:
    """Overlay font size in pixels: a performer line (up to about 100 monospaced characters,
    each 0.6 em wide) fits the width, and five lines take under a fifth of the height."""
    return int(np.clip(min(size[1] / 38, size[0] / 100 / 0.6), 8, 16))


class Viewer:
    def __init__(self, ctx, size: tuple[int, int] = (1280, 720), layout: str = "side", spacing: float = DEFAULT_SPACING,
                 clock=time.monotonic, show_text: bool = True, samples: int = 4) -> None:
        if layout not in LAYOUTS:
            raise ValueError(f"layout must be one of {LAYOUTS}")
        self.ctx = ctx
        self.size = size
        self.layout = layout
        self.spacing = spacing
        self.clock = clock
        self.show_text = show_text
        self.samples = samples
        self.table = PerformerTable(humanoid_skeleton_default())
        self.scene = Scene(ctx, text_size(size))
        self.camera = OrbitCamera()
        self.builder = CapsuleBuilder()
        self.follow: str | int | None = "all"  # "all", a slot number, or None (free camera)
        self.zoom = 1.0  # the user's scroll on top of the automatic framing distance
        self.listening = "-"
        self.ignored: dict[str, int] = {}  # reason -> count, from the intake
        self._framed_once = False
        self._last_render: float | None = None
        self._render_times: deque = deque(maxlen=240)
        self._offscreen = None
        self.listeners: list = []
        self.status_poller = None
        self._lines: list | None = None
        self._lines_time, self._lines_count = 0.0, 0

    # ------------------------------------------------------------------ input
    def listen(self, bind: str = "127.0.0.1", port: int = 39539, role: str = "restyled",
               use_stream_offsets: bool = True, slot: int | None = None):
        """Start receiving VMC on ``bind:port`` (port 0: any free port; see ``.address``).
        ``slot``: where performers heard there stand (default: in order of appearance)."""
        from .listener import Intake, Listener

        listener = Listener(Intake(self.table, role, self.clock, use_stream_offsets, slot), bind, port).start()
        self.listeners.append(listener)
        self.listening = ", ".join(f"{lst.address[0]}:{lst.address[1]} {lst.intake.role}" for lst in self.listeners)
        return listener

    def poll_status(self, host: str = "127.0.0.1", port: int = 39570):
        """Ask the daemon's control port for style, intensity and restyle latency."""
        from .status import StatusPoller

        self.status_poller = StatusPoller(host, port, clock=self.clock).start()
        return self.status_poller

    def ignored_counts(self) -> dict[str, int]:
        total: dict[str, int] = {}
        for lst in self.listeners:
            for reason, n in lst.ignored().items():
                total[reason] = total.get(reason, 0) + n
        return total

    def close(self) -> None:
        for lst in self.listeners:
            lst.close()
        self.listeners.clear()
        if self.status_poller is not None:
            self.status_poller.close()
            self.status_poller = None

    def __enter__(self) -> "Viewer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ one frame
    def fps(self, now: float) -> float:
        recent = [t for t in self._render_times if now - t <= 1.0]
        return (len(recent) - 1) / (recent[-1] - recent[0]) if len(recent) > 1 and recent[-1] > recent[0] else 0.0

    def render(self, size: tuple[int, int] | None = None, now: float | None = None) -> None:
        """Draw one frame into the currently bound framebuffer."""
        now = self.clock() if now is None else now
        size = size or self.size
        performers = self.table.snapshot(now)
        if self.listeners:
            self.ignored = self.ignored_counts()
        placements = place(performers, self.layout, self.spacing, now)
        capsules = self.builder.build(performers, placements) if performers else Capsules.empty()
        lines = self._overlay(performers, now)
        self._update_camera(performers, capsules, size, now)
        self._render_times.append(now)
        self.scene.render(self.camera, size, capsules, lines)

    def _overlay(self, performers, now: float) -> list:
        """Overlay lines, refreshed a few times a second: figures that change every frame
        cannot be read anyway, and an unchanged text skips its rebuild and upload."""
        if not self.show_text:
            return []
        if (self._lines is None or now - self._lines_time >= TEXT_REFRESH_S or now < self._lines_time
                or self._lines_count != len(performers)):
            status = self.status_poller.latest() if self.status_poller is not None else None
            self._lines = overlay_lines(performers, now, self.fps(now), self.listening, self.ignored, self.layout,
                                        status)
            self._lines_time, self._lines_count = now, len(performers)
        return self._lines

    def _text_reserve(self, size) -> float:
        """The fraction of the picture's height the overlay panel covers (bottom-left)."""
        if not self.show_text or not self._lines:
            return 0.0
        return (len(self._lines) * self.scene.text.atlas.cell_h + 22) / max(size[1], 1)

    def _update_camera(self, performers, capsules: Capsules, size, now: float) -> None:
        dt = 0.0 if self._last_render is None else max(0.0, now - self._last_render)
        self._last_render = now
        if self.follow is None or not performers:
            return
        corners, hips = capsules.bounds(None if self.follow == "all" else self.follow)
        if not len(corners):
            return
        # Horizontally the camera tracks the hips at once (a walking performer must not
        # drift out of a lagging view); the box of all bones, which arm swings shake, only
        # sets the height and the distance, and those ease in.
        box_centre = (corners.min(axis=0) + corners.max(axis=0)) / 2
        shift = np.array([1.0, 0.0, 1.0]) * (hips.mean(axis=0) - box_centre)
        goal = OrbitCamera(yaw=self.camera.yaw, pitch=self.camera.pitch, fov=self.camera.fov)
        goal.frame(corners + shift, size[0] / max(size[1], 1), self._text_reserve(size))
        goal.distance *= self.zoom
        k = 1.0 if not self._framed_once else 1.0 - np.exp(-dt / FOLLOW_SMOOTHING_S)  # first sight snaps
        self._framed_once = True
        eased = self.camera.target + k * (goal.target - self.camera.target)
        self.camera.target = np.array([goal.target[0], eased[1], goal.target[2]])
        self.camera.distance += k * (goal.distance - self.camera.distance)

    # ------------------------------------------------------------------ controls (window and tests)
    def frame_all(self) -> None:
        self.follow, self.zoom, self._framed_once = "all", 1.0, False

    def frame_slot(self, slot: int) -> None:
        self.follow, self.zoom, self._framed_once = slot, 1.0, False

    def toggle_layout(self) -> None:
        self.layout = LAYOUTS[(LAYOUTS.index(self.layout) + 1) % len(LAYOUTS)]
        self._framed_once = False
        self._lines = None

    # ------------------------------------------------------------------ headless
    def _target(self):
        """An offscreen target of ``self.size``: multisampled colour+depth, resolved into a
        plain colour buffer for reading (llvmpipe supports 4x MSAA; 0 disables it)."""
        if self._offscreen is None or self._offscreen[0] != self.size:
            ctx, size = self.ctx, self.size
            samples = self.samples if self.samples and self.samples <= ctx.max_samples else 0
            draw = ctx.framebuffer(color_attachments=[ctx.renderbuffer(size, 4, samples=samples)],
                                   depth_attachment=ctx.depth_renderbuffer(size, samples=samples))
            resolve = ctx.framebuffer(color_attachments=[ctx.renderbuffer(size, 4)]) if samples else draw
            self._offscreen = (self.size, draw, resolve)
        return self._offscreen[1], self._offscreen[2]

    def render_offscreen(self, now: float | None = None, resolve_into=None) -> None:
        """Render into the offscreen target, then resolve it into ``resolve_into`` (a window's
        screen, of the same size) or the readable buffer."""
        draw, resolve = self._target()
        draw.use()
        self.render(self.size, now)
        dst = resolve if resolve_into is None else resolve_into
        if dst is not draw:
            self.ctx.copy_framebuffer(dst, draw)

    def read_pixels(self) -> np.ndarray:
        """The last offscreen frame as an (H, W, 3) uint8 array, top row first."""
        _, resolve = self._target()
        data = resolve.read(components=3, alignment=1)
        w, h = self.size
        return np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1].copy()

    def save_png(self, path: str | Path) -> Path:
        from PIL import Image

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(self.read_pixels()).save(path, optimize=True)
        return path

    def run_headless(self, until_time: float, snapshot_path: str | Path | None = None,
                     fps: float = 30.0) -> Path | None:
        """Render offscreen at ``fps`` until the clock reaches ``until_time``, then save the
        last frame to ``snapshot_path`` (if given). Listeners keep receiving meanwhile."""
        from .headless import render_until

        render_until(self, until_time, fps)
        return self.save_png(snapshot_path) if snapshot_path is not None else None

    def run_frames(self, frames_dir: str | Path, duration: float, fps: float = 30.0) -> list[Path]:
        """Render ``duration`` seconds as numbered PNGs frame_00000.png... in ``frames_dir``."""
        from .headless import write_frames

        return write_frames(self, Path(frames_dir), duration, fps)
