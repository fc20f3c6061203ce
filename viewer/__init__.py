"""stylecast.viewer: an OpenGL (moderngl, core 3.3) VMC marionette for seeing restyles.

It listens for VMC like any marionette and never imports the daemon or the models; see
viewer/README.md. For tests and scripts:

    from stylecast.viewer.context import create_headless_context
    from stylecast.viewer.app import Viewer
    with Viewer(create_headless_context(), size=(640, 360)) as v:
        v.listen("127.0.0.1", 39539, "restyled"); v.listen("127.0.0.1", 39541, "input")
        v.run_headless(v.clock() + 2.0, "a.png"); v.run_headless(v.clock() + 1.0, "b.png")

or ``stylecast.viewer.headless.view_headless(...)`` for listener + renderer in one call.
Heavy imports (moderngl, PIL, pyglet) happen inside the modules that need them, so
importing this package is cheap.
"""
