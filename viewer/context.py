"""The one place GL contexts are made: headless through EGL, or a desktop window.

Failures a user can meet (no moderngl, no EGL, no display) become one UserError sentence
naming the fix; the CLI prints it without a traceback.
"""

from __future__ import annotations

import os
import sys

from stylecast.motion.errors import UserError

GL_VERSION = 330
INSTALL_HINT = "install the viewer extra (pip install 'stylecast[viewer]')"
EGL_HINT = ("install Mesa's EGL and software renderer (Debian/Ubuntu: apt-get install libegl1 "
            "libgl1-mesa-dri), or run on a desktop without --snapshot/--frames")


def _moderngl():
    try:
        import moderngl
    except ImportError:
        raise UserError(f"the viewer needs moderngl, which is not installed: {INSTALL_HINT}") from None
    return moderngl


def create_headless_context():
    """A standalone OpenGL 3.3 core context through EGL (Mesa llvmpipe without a GPU)."""
    moderngl = _moderngl()
    # Mesa's loader prints its own warnings on stderr when a driver is missing; our error
    # below already says what failed, so keep the output to that one sentence.
    os.environ.setdefault("EGL_LOG_LEVEL", "fatal")
    try:
        return moderngl.create_standalone_context(backend="egl", require=GL_VERSION)
    except Exception as exc:  # moderngl/glcontext raise plain Exception for every EGL failure
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise UserError(f"cannot create a headless OpenGL {GL_VERSION // 100}.{GL_VERSION % 100 // 10} "
                        f"context through EGL ({reason}): {EGL_HINT}") from None


def has_display() -> bool:
    if sys.platform in ("win32", "darwin"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def create_window(size: tuple[int, int], title: str):
    """A moderngl-window window (pyglet, or whatever MODERNGL_WINDOW names) with a 3.3 context."""
    _moderngl()
    if not has_display():
        raise UserError("no display to open a window on (DISPLAY and WAYLAND_DISPLAY are unset): "
                        "run on a desktop, or render headless with --snapshot out.png or --frames DIR")
    try:
        import moderngl_window
        from moderngl_window.conf import settings

        cls = moderngl_window.get_local_window_cls(None)
        settings.WINDOW["gl_version"] = (GL_VERSION // 100, GL_VERSION % 100 // 10)
        # samples=0: the viewer multisamples offscreen, once it knows the renderer.
        window = cls(title=title, size=size, gl_version=settings.WINDOW["gl_version"], resizable=True,
                     vsync=True, samples=0)
        moderngl_window.activate_context(window=window)
    except UserError:
        raise
    except Exception as exc:  # any window toolkit failure: missing library, refused display
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise UserError(f"cannot open a window ({reason}): check that the display is reachable and pyglet is "
                        f"installed, or render headless with --snapshot out.png") from None
    return window
