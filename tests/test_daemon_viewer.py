"""The whole picture in CI: the real daemon (`stylecast serve`, a subprocess) replays a
Bandai clip and sends restyled and input VMC to the viewer, which renders headless
through EGL (Mesa's llvmpipe)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from tests.test_viewer import blue_mask, orange_mask

REPO = Path(__file__).resolve().parents[1]
MODEL = REPO / "models" / "checkpoints" / "normal2exhausted.safetensors"


def wait_until_serving(proc: subprocess.Popen, timeout: float = 90.0) -> list[str]:
    lines, deadline = [], time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = proc.stderr.readline()
        lines.append(line)
        if "serving" in line or not line:
            return lines
    return lines


def test_daemon_and_headless_viewer_show_input_and_restyle_side_by_side(bandai_root, tmp_path):
    from stylecast.viewer.app import Viewer
    from stylecast.viewer.context import create_headless_context

    clip = sorted((bandai_root / "dataset-2" / "data").glob("dataset-2_wave-both-hands_normal_*.bvh.gz"))[0]
    ctx = create_headless_context()
    with Viewer(ctx, size=(480, 320), samples=0, show_text=False) as viewer:
        restyled_port = viewer.listen("127.0.0.1", 0, "restyled").address[1]
        input_port = viewer.listen("127.0.0.1", 0, "input").address[1]
        model = [] if MODEL.exists() else ["--model", "identity"]
        proc = subprocess.Popen(
            [sys.executable, "-m", "stylecast", "serve", "--source", f"bvh://{clip}?loop=1",
             "--out", f"vmc://127.0.0.1:{restyled_port}", "--out-input", f"vmc://127.0.0.1:{input_port}",
             "--control", "off", "--hop", "15", *model],
            cwd=REPO, stderr=subprocess.PIPE, text=True)
        try:
            started = wait_until_serving(proc)
            assert proc.poll() is None, "".join(started) + proc.stderr.read()
            first = viewer.run_headless(viewer.clock() + 2.0, tmp_path / "first.png", fps=15)
            second = viewer.run_headless(viewer.clock() + 0.7, tmp_path / "second.png", fps=15)
            assert ctx.error == "GL_NO_ERROR"
            performers = viewer.table.snapshot(viewer.clock())
            assert {p.role for p in performers} == {"restyled", "input"}
            assert min(p.frames for p in performers) > 30
        finally:
            proc.terminate()
            proc.wait(timeout=20)
    from PIL import Image

    a, b = (np.asarray(Image.open(p).convert("RGB")) for p in (first, second))
    width = a.shape[1]
    for shot in (a, b):
        orange_x, blue_x = np.nonzero(orange_mask(shot))[1], np.nonzero(blue_mask(shot))[1]
        assert len(orange_x) > 150 and len(blue_x) > 150  # both skeletons drawn
        assert blue_x.mean() < width / 2 < orange_x.mean()  # input on the left, restyled on the right
    assert (orange_mask(a) != orange_mask(b)).sum() > 50  # the waving performer moved
