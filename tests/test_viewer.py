"""The viewer, headless through EGL (Mesa llvmpipe in CI): pixels where the skeleton must be,
motion visible between snapshots, a real loopback VMC stream, bad packets survived."""

from __future__ import annotations

import os
import socket
import struct
import threading
import time

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

pytest.importorskip("moderngl")

from stylecast.drivers.vmc.osc_packets import encode_bundle, encode_message  # noqa: E402
from stylecast.drivers.vmc.vmc_out import VmcSender, encode_frame  # noqa: E402
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default  # noqa: E402
from stylecast.viewer.app import Viewer  # noqa: E402
from stylecast.viewer.camera import OrbitCamera  # noqa: E402
from stylecast.viewer.context import create_headless_context  # noqa: E402
from stylecast.viewer.geometry import capsule_mesh  # noqa: E402
from stylecast.viewer.headless import view_headless  # noqa: E402
from stylecast.viewer.listener import Intake  # noqa: E402
from stylecast.viewer.posing import CM_TO_M  # noqa: E402
from stylecast.viewer.scene import BACKGROUND  # noqa: E402
from stylecast.viewer.window import Controls  # noqa: E402

SIZE = (320, 240)
SKELETON = humanoid_skeleton_default()
HIPS_CM = np.array([0.0, 95.0, 0.0])
SENDER = ("127.0.0.1", 50000)


@pytest.fixture(scope="module")
def ctx():
    return create_headless_context()


class FakeClock:
    def __init__(self, t: float = 100.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


def arm_pose(angle_deg: float) -> np.ndarray:
    """T-pose with the left upper arm turned ``angle_deg`` about +Z (positive: raised)."""
    rots = np.tile([0.0, 0.0, 0.0, 1.0], (len(HUMANOID_BONES), 1))
    rots[HUMANOID_BONES.index("LeftUpperArm")] = Rotation.from_euler("z", angle_deg, degrees=True).as_quat()
    return rots


def datagrams(angle_deg: float, t: float) -> list[bytes]:
    return encode_frame(HIPS_CM, arm_pose(angle_deg), SKELETON.offsets, t)


def fixed_camera_viewer(ctx, clock, **kw) -> Viewer:
    """A viewer whose camera does not follow, so pixel positions are known in advance."""
    v = Viewer(ctx, size=SIZE, clock=clock, show_text=False, samples=0, **kw)
    v.follow = None
    v.camera = OrbitCamera(target=np.array([0.0, 1.0, 0.0]), yaw=0.0, pitch=0.0, distance=4.0)
    return v


def project(viewer: Viewer, points_m: np.ndarray) -> np.ndarray:
    """World points (N, 3) metres -> pixel (x, y), origin top-left, as the scene draws them."""
    w, h = viewer.size
    m = viewer.camera.view_projection(w / h)
    p = np.c_[points_m, np.ones(len(points_m))] @ m.T
    ndc = p[:, :2] / p[:, 3:4]
    return np.c_[(ndc[:, 0] + 1) / 2 * w, (1 - ndc[:, 1]) / 2 * h]


def orange_mask(pixels: np.ndarray) -> np.ndarray:
    r, g, b = (pixels[..., i].astype(int) for i in range(3))
    return (r > 120) & (r - b > 80)


def blue_mask(pixels: np.ndarray) -> np.ndarray:
    r, g, b = (pixels[..., i].astype(int) for i in range(3))
    return (b > 120) & (b - r > 60)


def joints_m(rotations: np.ndarray) -> np.ndarray:
    from stylecast.viewer.posing import pose_world

    positions, _ = pose_world(SKELETON, HIPS_CM[None], rotations[None])
    return positions[0]


# ----------------------------------------------------------------------------- rendering

@pytest.mark.parametrize("detail", ["fine", "coarse"])
def test_capsule_triangles_face_outwards(detail):
    from stylecast.viewer.scene import CAPSULE_DETAIL

    verts, tris = capsule_mesh(*CAPSULE_DETAIL[detail])
    p = verts[:, :3] + np.c_[np.zeros(len(verts)), verts[:, 3] * 2.0, np.zeros(len(verts))]  # a 2-long bone
    a, b, c = p[tris[:, 0]], p[tris[:, 1]], p[tris[:, 2]]
    normal = np.cross(b - a, c - a)
    centre = np.array([0.0, 1.0, 0.0])
    outward = np.einsum("ij,ij->i", normal, (a + b + c) / 3 - centre)
    nondegenerate = np.linalg.norm(normal, axis=1) > 1e-9
    assert np.all(outward[nondegenerate] > 0)  # counter-clockwise from outside: culling keeps them


def test_known_pose_draws_skeleton_where_projection_says(ctx):
    clock = FakeClock()
    v = fixed_camera_viewer(ctx, clock)
    intake = Intake(v.table, "restyled", clock)
    for d in datagrams(60.0, 0.0):
        intake.feed(d, SENDER)
    v.render_offscreen()
    assert ctx.error == "GL_NO_ERROR"
    px = v.read_pixels()
    mask = orange_mask(px)
    assert mask.sum() > 500

    joints = project(v, joints_m(arm_pose(60.0)))
    ys, xs = np.nonzero(mask)
    margin = 20  # capsule radius and head/hand tips beyond the joints, in pixels at this zoom
    assert xs.min() >= joints[:, 0].min() - margin and xs.max() <= joints[:, 0].max() + margin
    assert ys.min() >= joints[:, 1].min() - margin - 10 and ys.max() <= joints[:, 1].max() + margin
    # Every joint is covered by skeleton pixels (within a few pixels).
    for name in ("Hips", "Head", "LeftHand", "RightHand", "LeftFoot", "RightFoot"):
        x, y = joints[HUMANOID_BONES.index(name)].round().astype(int)
        assert mask[max(0, y - 4):y + 5, max(0, x - 4):x + 5].any(), name
    # Facing the camera the performer's left (+X) is on screen right, and the raised left
    # hand is higher than the right one (a handedness slip would swap or lower it).
    lh, rh = joints[HUMANOID_BONES.index("LeftHand")], joints[HUMANOID_BONES.index("RightHand")]
    assert lh[0] > rh[0] and lh[1] < rh[1] - 30
    # Away from the skeleton the image is background (the top corners are above the grid).
    assert np.abs(px[0, 0].astype(int) - np.round(np.array(BACKGROUND) * 255)).max() <= 2


def test_side_by_side_and_overlay(ctx):
    clock = FakeClock()
    v = fixed_camera_viewer(ctx, clock)
    restyled, source = Intake(v.table, "restyled", clock), Intake(v.table, "input", clock)
    for d in datagrams(45.0, 0.0):
        restyled.feed(d, SENDER)
        source.feed(d, SENDER)
    v.render_offscreen()
    px = v.read_pixels()
    blue_x, orange_x = np.nonzero(blue_mask(px))[1], np.nonzero(orange_mask(px))[1]
    assert len(blue_x) > 300 and len(orange_x) > 300
    assert blue_x.mean() < orange_x.mean() - 50  # input at -X: screen left of the restyled one

    # Overlay: one spot; where the input's arm differs (down instead of up) its translucent
    # shell shows blue over the background, and the restyled arm stays orange.
    v.layout = "overlay"
    for d in datagrams(-60.0, 1.0):
        source.feed(d, SENDER)
    v.render_offscreen()
    assert ctx.error == "GL_NO_ERROR"
    px = v.read_pixels()
    torso = np.abs(px[:150].astype(int) - np.round(np.array(BACKGROUND) * 255)).sum(axis=2) > 60  # above the floor
    assert abs(np.nonzero(torso)[1].mean() - SIZE[0] / 2) < 25  # both figures on one spot, mid-screen
    blue, orange = blue_mask(px), orange_mask(px)
    for angle, mask in ((-60.0, blue), (45.0, orange)):
        x, y = project(v, joints_m(arm_pose(angle)))[HUMANOID_BONES.index("LeftHand")].round().astype(int)
        assert mask[y - 4:y + 5, x - 4:x + 5].any(), angle


def test_two_snapshots_of_a_moving_stream_differ(ctx):
    clock = FakeClock()
    v = fixed_camera_viewer(ctx, clock)
    intake = Intake(v.table, "restyled", clock)
    shots = []
    for k, angle in enumerate((-40.0, 70.0)):
        clock.t += 1.0
        for d in datagrams(angle, float(k)):
            intake.feed(d, SENDER)
        v.render_offscreen()
        shots.append(orange_mask(v.read_pixels()))
    changed = (shots[0] != shots[1]).sum()
    assert changed > 300
    # Only the arm moved: the rest of the body (left half of the image) is unchanged.
    assert (shots[0][:, : SIZE[0] // 2] != shots[1][:, : SIZE[0] // 2]).sum() < 20


def _fake_daemon(stop: threading.Event) -> int:
    """A control port that answers /stylecast/status as the daemon documents it."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(0.05)
    reply = [encode_bundle([
        encode_message("/stylecast/status/daemon", "exhausted", "normal2exhausted", 1, 600, 0, 0, 0),
        encode_message("/stylecast/status/performer", "walk", 600, 585, 251.4, 264.8, 0, 0, 0, 0, 0.75, 0)]),
        encode_message("/stylecast/status/performer", "x", 1.0),  # malformed: skipped
    ]

    def serve() -> None:
        with sock:
            while not stop.is_set():
                try:
                    data, addr = sock.recvfrom(1500)
                except OSError:
                    continue
                if data.startswith(b"/stylecast/status\x00"):
                    for d in reply:
                        sock.sendto(d, addr)

    threading.Thread(target=serve, daemon=True).start()
    return sock.getsockname()[1]


def test_overlay_shows_rate_latency_and_the_daemon_status(ctx):
    from stylecast.viewer.compose import overlay_lines

    stop = threading.Event()
    with Viewer(ctx, size=(640, 240), samples=0) as v:
        v.poll_status("127.0.0.1", _fake_daemon(stop))
        intake = Intake(v.table, "restyled", v.clock)
        t0 = v.clock()
        for k in range(30):
            now = t0 + k / 60
            for d in datagrams(10.0, now - 0.004):  # T on our monotonic clock, 4 ms ago
                intake.feed(d, SENDER, now)
        deadline = time.monotonic() + 5
        while v.status_poller.latest() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        stop.set()
        status = v.status_poller.latest()
        assert status is not None and status.style == "exhausted" and len(status.performers) == 1
        (perf,) = v.table.snapshot(t0 + 29 / 60)
        text = "\n".join(t for t, _ in overlay_lines([perf], t0 + 29 / 60, 30.0, "x", {}, "side", status))
        # /VMC/Ext/T travels as a float32, so the 4 ms is read through its rounding at t0's
        # magnitude (2 ms steps on a host up for 5 hours): expect exactly what the wire carries.
        wire = sorted((t0 + k / 60) - float(np.float32(t0 + k / 60 - 0.004)) for k in range(30))
        assert "60.0 Hz" in text and f"latency {wire[15] * 1e3:5.1f} ms" in text
        assert abs(wire[15] - 0.004) <= float(np.spacing(np.float32(t0)))  # and it is the 4 ms sent
        assert "style exhausted" in text and "p50 251 p99 265 ms" in text and "intensity 0.75" in text
        v.render_offscreen()
        assert ctx.error == "GL_NO_ERROR"
        panel = v.read_pixels()[-90:-12, 12:400]  # the panel sits bottom-left
        assert (panel.max(axis=2) > 200).sum() > 200  # white/orange glyphs on the dark panel


def test_latency_from_a_foreign_clock_is_shown_as_jitter():
    from stylecast.viewer.performers import PerformerTable

    table = PerformerTable(SKELETON)
    for k in range(10):  # a sender whose T starts at 0 while our clock reads 1000 s
        table.update_pose("restyled", "a", HIPS_CM, arm_pose(0.0), k / 60, 1000 + k / 60 + (0.010 if k == 9 else 0))
    (perf,) = table.snapshot(1000.2)
    kind, value = perf.latency()
    assert kind == "jitter" and value == pytest.approx(0.0)  # the median of recent frames
    assert 0.0 <= value < 0.011


# ----------------------------------------------------------------------------- bad input

def test_malformed_nan_and_unknown_bone_packets_are_ignored(ctx):
    clock = FakeClock()
    v = fixed_camera_viewer(ctx, clock)
    intake = Intake(v.table, "restyled", clock)
    for d in datagrams(30.0, 0.0):
        intake.feed(d, SENDER)
    nan_bone = encode_message("/VMC/Ext/Bone/Pos", "LeftUpperArm", 0.0, 0.0, 0.0, float("nan"), 0.0, 0.0, 1.0)
    bad = [
        b"", b"\x00\x01\x02", b"garbage!", b"#bundle\x00" + b"\xff" * 12,
        b"#bundle\x00" + bytes(8) + struct.pack(">i", -4),
        encode_message("/VMC/Ext/Bone/Pos", "LeftPinkyProximal", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0),
        encode_message("/VMC/Ext/Bone/Pos", "NoSuchBone", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0),
        encode_message("/VMC/Ext/Bone/Pos", "Head", "x", 1, 2),  # wrong types
        encode_message("/VMC/Ext/Bone/Pos", "Head"),  # missing arguments
        encode_message("/VMC/Ext/Root/Pos", "root", float("inf"), 0.0, 0.0, 0.0, 0.0, 0.0, 1.0),
        encode_message("/VMC/Ext/T", float("nan")),
        encode_message("/somewhere/else", 1),
        encode_bundle([nan_bone, encode_message("/VMC/Ext/T", 1.0)]),
        encode_message("/stylecast/status/daemon", 3),
    ]
    for d in bad:
        intake.feed(d, SENDER)
    for d in datagrams(30.0, 2.0):
        intake.feed(d, SENDER)
    (perf,) = v.table.snapshot(clock.t)
    assert np.all(np.isfinite(perf.rotations)) and np.all(np.isfinite(perf.root))
    ignored = intake.ignored()
    for reason in ("non_finite", "ignored_bone", "wrong_type", "missing_args", "unknown_address"):
        assert ignored.get(reason, 0) > 0, reason
    v.render_offscreen()
    assert ctx.error == "GL_NO_ERROR"
    assert orange_mask(v.read_pixels()).sum() > 500


def test_non_finite_values_that_reach_the_table_keep_the_previous_pose():
    from stylecast.viewer.performers import PerformerTable

    table = PerformerTable(SKELETON)
    table.update_pose("restyled", "a", HIPS_CM, arm_pose(30.0), 0.0, 0.0)
    rots = arm_pose(50.0)
    rots[3] = np.nan
    rots[5] = 0.0
    table.update_pose("restyled", "a", np.array([np.nan, 0, 0]), rots, float("nan"), 0.1)
    table.update_pose("restyled", "a", HIPS_CM, np.zeros((3, 4)), 0.2, 0.2)  # wrong shape
    (perf,) = table.snapshot(0.2)
    assert np.allclose(perf.rotations[3], arm_pose(30.0)[3]) and np.allclose(perf.root, HIPS_CM)
    assert perf.ignored_values == 3 + len(HUMANOID_BONES)


# ----------------------------------------------------------------------------- real sockets

def _stream(ports: list[int], stop: threading.Event, errors: list) -> None:
    """60 Hz VMC: a waving arm on the first port (restyled), a still T-pose on the second."""
    try:
        senders = [VmcSender([("127.0.0.1", p)]) for p in ports]
        t0, k = time.monotonic(), 0
        while not stop.is_set():
            t = k / 60
            senders[0].send_frame(HIPS_CM, arm_pose(70 * np.sin(2 * np.pi * t)), SKELETON.offsets, t)
            for s in senders[1:]:
                s.send_frame(HIPS_CM, arm_pose(0.0), SKELETON.offsets, t)
            k += 1
            time.sleep(max(0.0, t0 + k / 60 - time.monotonic()))
    except Exception as exc:  # surfaced by the test, not lost in a thread
        errors.append(exc)


def test_loopback_udp_stream_two_snapshots(ctx, tmp_path):
    stop, errors = threading.Event(), []
    with Viewer(ctx, size=SIZE, samples=0) as v:
        ports = [v.listen("127.0.0.1", 0, "restyled").address[1], v.listen("127.0.0.1", 0, "input").address[1]]
        sender = threading.Thread(target=_stream, args=(ports, stop, errors), daemon=True)
        sender.start()
        try:
            a = v.run_headless(v.clock() + 0.6, tmp_path / "a.png", fps=20)
            # Garbage on the live socket must not stop the listener.
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
                for junk in (b"\xff" * 7, b"#bundle\x00" + b"\x00" * 5, b"/VMC/Ext/Bone/Pos\x00\x00\x00,ff\x00"):
                    s.sendto(junk, ("127.0.0.1", ports[0]))
            b = v.run_headless(v.clock() + 0.25, tmp_path / "b.png", fps=20)
        finally:
            stop.set()
            sender.join()
        assert not errors
        assert ctx.error == "GL_NO_ERROR"
        assert all(lst._thread.is_alive() for lst in v.listeners)
        perfs = v.table.snapshot(v.clock())
        assert {p.role for p in perfs} == {"restyled", "input"} and min(p.frames for p in perfs) > 10
        assert sum(v.ignored_counts().values()) >= 3
    from PIL import Image

    pa, pb = (np.asarray(Image.open(p).convert("RGB")) for p in (a, b))
    assert orange_mask(pa).sum() > 200 and blue_mask(pa).sum() > 200
    assert (orange_mask(pa) != orange_mask(pb)).sum() > 50  # the waving arm moved


def test_view_headless_writes_snapshot_and_frames(ctx, tmp_path):
    stop, errors = threading.Event(), []

    def start(viewer):
        ports = [lst.address[1] for lst in viewer.listeners]
        threading.Thread(target=_stream, args=(ports, stop, errors), daemon=True).start()

    try:
        result = view_headless(port=0, input_port=0, after=0.3, snapshot=tmp_path / "s.png",
                               frames_dir=tmp_path / "frames", duration=0.3, fps=10, size=SIZE, ctx=ctx,
                               on_listening=start)
    finally:
        stop.set()
    assert not errors
    assert result.snapshot.exists() and len(result.frames) == 3 and all(p.exists() for p in result.frames)
    assert len(result.performers) == 2 and all(n > 5 for n in result.performers.values())
    assert "llvmpipe" in result.renderer or result.renderer


def test_port_range_gives_each_daemon_performer_its_slot(ctx):
    from stylecast.viewer.headless import listen_all

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:  # a free base with a free neighbour
        probe.bind(("127.0.0.1", 0))
        base = probe.getsockname()[1]
    base = base if base < 65000 else 40000
    with Viewer(ctx, size=SIZE, samples=0) as v:
        listen_all(v, base, "127.0.0.1", base + 4, performers=2)
        assert [(lst.address[1], lst.intake.role, lst.intake.slot) for lst in v.listeners] == [
            (base, "restyled", 0), (base + 4, "input", 0), (base + 1, "restyled", 1), (base + 5, "input", 1)]
        with VmcSender([("127.0.0.1", base + 1)]) as s:  # only the second performer is live
            for k in range(5):
                s.send_frame(HIPS_CM, arm_pose(0.0), SKELETON.offsets, k / 60)
                time.sleep(0.01)
        deadline = time.monotonic() + 3
        while not len(v.table) and time.monotonic() < deadline:
            time.sleep(0.02)
        (perf,) = v.table.snapshot(v.clock())
        assert perf.slot == 1 and perf.role == "restyled"


# ----------------------------------------------------------------------------- CLI and controls

def test_cli_snapshot_without_a_stream(tmp_path, capsys):
    from stylecast.cli import main

    out = tmp_path / "empty.png"
    assert main(["view", "--port", "0", "--snapshot", str(out), "--after", "0.1", "--width", "160",
                 "--height", "120"]) == 0
    assert out.exists() and "heard no performer" in capsys.readouterr().out


def test_cli_says_one_sentence_without_display_or_egl(monkeypatch, capsys):
    import moderngl

    from stylecast.cli import main

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    assert main(["view"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no display" in err and "--snapshot" in err

    def no_egl(**kwargs):
        raise Exception("eglInitialize failed (0x3001)")

    monkeypatch.setattr(moderngl, "create_standalone_context", no_egl)
    assert main(["view", "--snapshot", "x.png"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "EGL" in err and "libegl1" in err and "Traceback" not in err


def test_cli_rejects_bad_options(capsys):
    from stylecast.cli import main

    assert main(["view", "--port", "39539", "--input-port", "39539", "--snapshot", "x.png"]) == 2
    assert main(["view", "--width", "0", "--snapshot", "x.png"]) == 2
    assert capsys.readouterr().err.count("stylecast: error:") == 2


WINDOW_SCRIPT = """
import threading, time
import moderngl_window as mglw
from stylecast.viewer.app import Viewer
from stylecast.viewer.window import run_window
state, errors = {}, set()
plain_render = Viewer.render
def render(self, *args, **kwargs):  # GL state is read on the GL thread, never from `later`
    plain_render(self, *args, **kwargs)
    errors.add(self.ctx.error)
Viewer.render = render
def start(viewer):
    viewer.listen("127.0.0.1", 0)
    def later():
        time.sleep(1.0)
        w = mglw.window()
        w.key_event_func(w.keys.L, w.keys.ACTION_PRESS, None)
        w.mouse_drag_event_func(0, 0, 40, 10)
        time.sleep(0.3)
        state["s"] = (viewer.layout, viewer.camera.yaw != 20.0, len(viewer._render_times) > 5)
        w.is_closing = True  # a flag the loop reads; close() from this thread would race the GL
    threading.Thread(target=later, daemon=True).start()
run_window((320, 240), "side", 1.8, start)
print(state["s"], sorted(errors))
"""


@pytest.mark.slow
def test_window_opens_renders_and_takes_events_under_xvfb(tmp_path):
    import shutil
    import subprocess
    import sys

    if shutil.which("Xvfb") is None:
        pytest.skip("Xvfb is not installed (apt-get install xvfb) - the desktop window is tested under it")
    # -displayfd: Xvfb picks a free display number and prints it once it accepts clients.
    xvfb = subprocess.Popen(["Xvfb", "-displayfd", "1", "-screen", "0", "640x480x24"], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
    try:
        display = ":" + xvfb.stdout.readline().strip()
        env = {**os.environ, "DISPLAY": display}
        out = subprocess.run([sys.executable, "-c", WINDOW_SCRIPT], env=env, capture_output=True, text=True,
                             timeout=60)
        assert out.returncode == 0, out.stderr
        assert out.stdout.strip().splitlines()[-1] == "('overlay', True, True) ['GL_NO_ERROR']"
    finally:
        xvfb.terminate()
        xvfb.wait(timeout=10)


def test_controls_orbit_zoom_frame_and_layout(ctx):
    v = Viewer(ctx, size=SIZE, samples=0)
    c = Controls(v)
    yaw, pitch = v.camera.yaw, v.camera.pitch
    c.drag(50, 20)
    assert v.camera.yaw != yaw and v.camera.pitch > pitch
    c.scroll(2)
    assert v.zoom < 1.0
    c.key("3")
    assert v.follow == 2
    c.key("f")
    assert v.follow == "all" and v.zoom == 1.0
    c.key("l")
    assert v.layout == "overlay"
    c.key("space")
    assert v.follow is None
    c.key("up")
    c.key("up")
    assert v.camera.pitch <= OrbitCamera.MAX_PITCH


def test_status_parser_skips_malformed_messages():
    from stylecast.viewer.status import parse_status

    ok = ("/stylecast/status/performer", "siiffiiiifi", ("p", 1, 1, 2.0, 3.0, 0, 0, 0, 0, 0.5, 1))
    assert parse_status([ok]) is None  # a performer line without its daemon line
    s = parse_status([("/stylecast/status/daemon", "ssiiiii", ("a", "m", 1, 0, 0, 0, 0)), ok,
                      ("/stylecast/status/performer", "siiffiiiifi",
                       ("q", 1, 1, float("nan"), 3.0, 0, 0, 0, 0, 0.5, 1)),
                      ("/stylecast/status/performer", "s", ("r",))])
    assert s.style == "a" and [p.name for p in s.performers] == ["p"] and s.performers[0].bypass


def test_pose_world_matches_the_shared_forward_kinematics():
    from stylecast.motion.clip import Clip, forward_kinematics
    from stylecast.viewer.posing import pose_world

    q = Rotation.random(3 * len(HUMANOID_BONES), random_state=7).as_quat().reshape(3, -1, 4)
    root = np.array([[0.0, 90.0, 0.0], [10.0, 80.0, -5.0], [-30.0, 100.0, 20.0]])
    ours, _ = pose_world(SKELETON, root, q)
    reference, _ = forward_kinematics(Clip(SKELETON, q, root, 60.0))
    assert np.allclose(ours, reference * CM_TO_M, atol=1e-9)


def test_camera_framing_keeps_every_corner_on_screen_above_the_panel():
    rng = np.random.default_rng(0)
    for _ in range(300):
        cam = OrbitCamera(yaw=rng.uniform(0, 360), pitch=rng.uniform(-5, 85))
        centre, size = rng.uniform(-3, 3, 3), rng.uniform(0.1, 4, 3)
        lo, hi = centre - size / 2, centre + size / 2
        reserve, aspect = rng.uniform(0, 0.4), rng.uniform(0.5, 2.5)
        cam.frame(np.array([lo, hi]), aspect, reserve)
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        p = np.c_[corners, np.ones(8)] @ cam.view_projection(aspect).T
        ndc = p[:, :2] / p[:, 3:]
        assert np.abs(ndc[:, 0]).max() <= 0.89 and ndc[:, 1].max() <= 0.89
        assert ndc[:, 1].min() >= -1 + 2 * reserve + 0.11


def test_camera_frames_points():
    cam = OrbitCamera()
    pts = np.array([[-2.0, 0.0, -0.5], [2.0, 1.8, 0.5]])
    cam.frame(pts, aspect=16 / 9)
    assert np.abs(cam.target - [0.0, 0.9, 0.0]).max() < 0.2  # aimed at (about) the box centre
    ndc = np.c_[pts, np.ones(2)] @ cam.view_projection(16 / 9).T
    assert np.all(np.abs(ndc[:, :2] / ndc[:, 3:]) < 1.0)  # both ends on screen
    assert CM_TO_M == 0.01
