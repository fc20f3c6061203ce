"""Headless loops: render offscreen on wall-clock time, save a snapshot or a frame sequence,
and ``view_headless``, the one call that runs listener + renderer for a while (CLI, tests).
"""

from __future__ import annotations

import queue
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from .layout import DEFAULT_SPACING


def _sleep_until(viewer, t: float) -> None:
    # Sleeping (instead of spinning) leaves the cores to the listener threads and to
    # whatever sends the stream; the sleep is in real seconds even with an injected clock.
    delay = t - viewer.clock()
    if delay > 0:
        time.sleep(min(delay, 0.1))


def render_until(viewer, until_time: float, fps: float = 30.0) -> int:
    """Render frames paced at ``fps`` until the viewer's clock reaches ``until_time``; the
    last frame is rendered at (or just after) ``until_time``. Returns frames rendered.
    Meant for a real clock: with an injected clock, advance it and call
    ``viewer.render_offscreen()`` directly (as tests/test_viewer.py does)."""
    period = 1.0 / fps
    frames = 0
    next_tick = viewer.clock()
    while True:
        now = viewer.clock()
        if now >= until_time:
            break
        if now >= next_tick:
            viewer.render_offscreen(now)
            frames += 1
            next_tick = max(next_tick + period, now)  # fall behind, never burst to catch up
        _sleep_until(viewer, min(next_tick, until_time))
    viewer.render_offscreen()
    return frames + 1


def write_frames(viewer, frames_dir: Path, duration: float, fps: float = 30.0) -> list[Path]:
    """Frame k is rendered at start + k / fps and written as frame_{k:05d}.png. PNG encoding
    runs on a writer thread so it overlaps the next render instead of delaying it."""
    from PIL import Image

    frames_dir.mkdir(parents=True, exist_ok=True)
    count = max(1, int(round(duration * fps)))
    todo: queue.Queue = queue.Queue(maxsize=8)
    paths = [frames_dir / f"frame_{k:05d}.png" for k in range(count)]

    def writer() -> None:
        while (item := todo.get()) is not None:
            path, pixels = item
            Image.fromarray(pixels).save(path, compress_level=1)

    thread = threading.Thread(target=writer, name="viewer-frames", daemon=True)
    thread.start()
    start = viewer.clock()
    try:
        for k, path in enumerate(paths):
            while viewer.clock() < start + k / fps:
                _sleep_until(viewer, start + k / fps)
            viewer.render_offscreen()
            todo.put((path, viewer.read_pixels()))
    finally:
        todo.put(None)
        thread.join()
    return paths


@dataclass
class ViewResult:
    snapshot: Path | None = None
    frames: list[Path] = field(default_factory=list)
    performers: dict[str, int] = field(default_factory=dict)  # "role host:port" -> frames received
    ignored: dict[str, int] = field(default_factory=dict)
    renderer: str = ""


def listen_all(viewer, port: int, bind: str, input_port: int | None, performers: int = 1,
               use_stream_offsets: bool = True, status: tuple[str, int] | None = None) -> None:
    """Ports as the daemon uses them: performer k on ``port + k`` (restyled) and
    ``input_port + k`` (input); slot k for both, so each pair stands together."""
    for k in range(performers):
        slot = k if performers > 1 else None
        viewer.listen(bind, port + k if port else 0, "restyled", use_stream_offsets, slot)
        if input_port is not None:
            viewer.listen(bind, input_port + k if input_port else 0, "input", use_stream_offsets, slot)
    if status is not None:
        viewer.poll_status(*status)


def view_headless(port: int = 39539, bind: str = "127.0.0.1", input_port: int | None = None,
                  after: float = 2.0, snapshot: str | Path | None = None, frames_dir: str | Path | None = None,
                  duration: float = 5.0, size: tuple[int, int] = (1280, 720), layout: str = "side",
                  spacing: float = DEFAULT_SPACING, samples: int | None = None, fps: float = 30.0, ctx=None,
                  on_listening=None, use_stream_offsets: bool = True, performers: int = 1,
                  status: tuple[str, int] | None = None) -> ViewResult:
    """Listen, render headless, and return what was seen. ``on_listening(viewer)`` is called
    once the ports are bound (a test starts its sender there, knowing the ports)."""
    from .app import Viewer
    from .context import create_headless_context

    ctx = ctx or create_headless_context()
    if samples is None:
        samples = 4 if frames_dir is None else 0  # a still may be slow; a sequence should keep up
    result = ViewResult(renderer=ctx.info.get("GL_RENDERER", "?"))
    with Viewer(ctx, size=size, layout=layout, spacing=spacing, samples=samples) as viewer:
        listen_all(viewer, port, bind, input_port, performers, use_stream_offsets, status)
        if on_listening is not None:
            on_listening(viewer)
        if frames_dir is not None:
            result.frames = viewer.run_frames(frames_dir, duration, fps)
        if snapshot is not None or frames_dir is None:
            result.snapshot = viewer.run_headless(viewer.clock() + after, snapshot, fps)
        now = viewer.clock()
        result.performers = {f"{p.role} {p.label}": p.frames for p in viewer.table.snapshot(now)}
        result.ignored = viewer.ignored_counts()
    return result
