"""The desktop window: moderngl-window events -> camera and layout controls -> Viewer.render.

``Controls`` is plain Python over key names, so the bindings are tested without a display.

    drag (left button)   orbit            scroll / + -   zoom
    arrow keys           orbit            F              frame every performer (and follow)
    1 .. 8               frame and follow that slot      Space  free camera (stop following)
    L                    side-by-side <-> overlay        H      hide / show the text overlay
    R                    reset the camera                Esc    quit
"""

from __future__ import annotations

import time

from .camera import OrbitCamera

ORBIT_DEG_PER_PIXEL = 0.4
ORBIT_DEG_PER_KEY = 10.0
ZOOM_PER_STEP = 1.12
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swiftshader", "software")


class Controls:
    def __init__(self, viewer) -> None:
        self.viewer = viewer

    def drag(self, dx: float, dy: float) -> None:
        self.viewer.camera.orbit(-dx * ORBIT_DEG_PER_PIXEL, dy * ORBIT_DEG_PER_PIXEL)

    def scroll(self, steps: float) -> None:
        self._zoom(ZOOM_PER_STEP ** -steps)

    def _zoom(self, factor: float) -> None:
        v = self.viewer
        v.zoom = min(max(v.zoom * factor, 0.1), 20.0)
        if v.follow is None:  # nothing re-frames a free camera: move it directly
            v.camera.zoom(factor)

    def key(self, name: str) -> None:
        v = self.viewer
        actions = {
            "left": lambda: v.camera.orbit(-ORBIT_DEG_PER_KEY, 0),
            "right": lambda: v.camera.orbit(ORBIT_DEG_PER_KEY, 0),
            "up": lambda: v.camera.orbit(0, ORBIT_DEG_PER_KEY),
            "down": lambda: v.camera.orbit(0, -ORBIT_DEG_PER_KEY),
            "plus": lambda: self._zoom(1 / ZOOM_PER_STEP), "minus": lambda: self._zoom(ZOOM_PER_STEP),
            "f": v.frame_all, "l": v.toggle_layout, "space": self._free,
            "h": lambda: setattr(v, "show_text", not v.show_text), "r": self._reset,
        }
        if name in actions:
            actions[name]()
        elif name.isdigit() and name != "0":
            v.frame_slot(int(name) - 1)

    def _free(self) -> None:
        self.viewer.follow = None

    def _reset(self) -> None:
        fresh = OrbitCamera()
        self.viewer.camera.yaw, self.viewer.camera.pitch = fresh.yaw, fresh.pitch
        self.viewer.frame_all()


def _key_names(keys) -> dict:
    names = {"LEFT": "left", "RIGHT": "right", "UP": "up", "DOWN": "down", "EQUAL": "plus", "NUMPAD_ADD": "plus",
             "MINUS": "minus", "NUMPAD_SUBTRACT": "minus", "SPACE": "space",
             **{c: c.lower() for c in "FLHR"}, **{f"NUMBER_{d}": str(d) for d in range(1, 9)}}
    return {getattr(keys, attr): name for attr, name in names.items()
            if getattr(keys, attr, "undefined") != "undefined"}


def software_renderer(ctx) -> bool:
    return any(s in ctx.info.get("GL_RENDERER", "").lower() for s in SOFTWARE_RENDERERS)


def run_window(size: tuple[int, int], layout: str, spacing: float, start_listening, msaa: int | None = None) -> None:
    """Open a window and draw what ``start_listening(viewer)`` makes it hear until the
    window closes (or Ctrl-C).

    Multisampling is done in the viewer's own offscreen target, resolved onto the window,
    so it can be chosen after the renderer is known: 4x on a GPU, off on a software
    renderer (llvmpipe shades samples on the CPU; 4x costs it most of its frame rate)."""
    from .app import Viewer
    from .context import create_window

    window = create_window(size, "stylecast view")
    samples = msaa if msaa is not None else (0 if software_renderer(window.ctx) else 4)
    viewer = Viewer(window.ctx, size=window.buffer_size, layout=layout, spacing=spacing, samples=samples)
    try:
        start_listening(viewer)
        controls = Controls(viewer)
        keys = window.keys
        names = _key_names(keys)

        def on_key(key, action, modifiers) -> None:
            if action == keys.ACTION_PRESS and key in names:
                controls.key(names[key])

        window.key_event_func = on_key
        window.mouse_drag_event_func = lambda x, y, dx, dy: controls.drag(dx, dy)
        window.mouse_scroll_event_func = lambda dx, dy: controls.scroll(dy)
        while not window.is_closing:
            if samples:
                viewer.size = window.buffer_size
                viewer.render_offscreen(resolve_into=window.ctx.screen)
            else:
                window.use()
                viewer.render(window.buffer_size)
            window.swap_buffers()  # also dispatches the toolkit's events
            if not window.visible:
                time.sleep(0.05)  # minimised: keep receiving, stop burning a core on frames
    except KeyboardInterrupt:
        pass
    finally:
        viewer.close()
        window.destroy()
