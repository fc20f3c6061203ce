"""``stylecast demo``: the no-hardware first run.

Finds a Bandai clip (argument, ``--clip``, ``$STYLECAST_DATA``, ``../shared/data`` next
to the repository or the working directory, else the walk shipped in the package, see
``clips.py``), replays it looping through the daemon
with the shipped model (pass-through with a clear message if the checkpoint is not
there) and sends VMC to 127.0.0.1:39539 (any VMC marionette, or the viewer) and the
unrestyled input to 127.0.0.1:39541; with the viewer installed and a display, it opens
the viewer on both, side by side.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

from stylecast.models.checkpoint import DEFAULT_MODEL  # the one definition; imports no torch
from stylecast.motion.errors import UserError

from .config import DaemonConfig
from .restylers import IdentityRestyler, load_restyler

log = logging.getLogger("stylecast.daemon")
DEFAULT_CLIP = "bandai/dataset-2/data/dataset-2_walk_normal_001.bvh.gz"
DEFAULT_OUT = "vmc://127.0.0.1:39539"
DEFAULT_INPUT_PORT = 39541  # the unrestyled input, for the viewer's before/after


def data_roots() -> list[Path]:
    here = Path(__file__).resolve()
    roots = []
    if os.environ.get("STYLECAST_DATA"):
        roots.append(Path(os.environ["STYLECAST_DATA"]))
    for base in (Path.cwd(), *here.parents):
        roots.append(base / "shared" / "data")
        roots.append(base.parent / "shared" / "data")
    return roots


def find_clip(given: str | None) -> Path:
    if given:
        path = Path(given)
        if not path.is_file():
            raise UserError(f"clip {given} does not exist; give a .bvh or .bvh.gz file")
        return path
    for root in data_roots():
        candidate = root / DEFAULT_CLIP
        if candidate.is_file():
            return candidate
        for pattern in ("bandai/dataset-2/data/*walk_normal*.bvh*", "bandai/dataset-1/data/*walk_normal*.bvh"):
            found = sorted(root.glob(pattern))
            if found:
                return found[0]
    from .clips import bundled_clip

    shipped = bundled_clip()
    if shipped is not None:
        return shipped
    raise UserError("no Bandai clip found (looked for ../shared/data next to the repository and the current "
                    "directory, and this install lacks its shipped clip); pass one: stylecast demo path/to/clip.bvh")


def demo_restyler(name: str, device: str = "auto"):
    try:
        return load_restyler(name, device)
    except Exception as exc:  # missing checkpoint, torch trouble: the demo still runs
        reason = str(exc).rstrip(".")
        print(f"stylecast demo: model {name!r} is not available ({reason}); running without restyling "
              f"(pass-through). Train or install the checkpoint to see the restyle.", file=sys.stderr)
        return IdentityRestyler()


def open_viewer(input_port: int | None) -> subprocess.Popen | None:
    try:
        import stylecast.viewer  # noqa: F401
        from stylecast.cli import build_parser
    except ImportError:
        print("stylecast demo: the viewer is not installed (pip install 'stylecast[viewer]')", file=sys.stderr)
        return None
    commands = build_parser()._subparsers._group_actions[0].choices  # registered subcommands
    name = next((c for c in ("view", "viewer") if c in commands), None)
    if name is None:
        print("stylecast demo: this install has no viewer command", file=sys.stderr)
        return None
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY") or sys.platform in ("win32", "darwin")):
        print("stylecast demo: no display for the viewer window; to see the motion headless run "
              "`stylecast view --snapshot demo.png --after 3` while the demo runs", file=sys.stderr)
        return None
    extra = ["--input-port", str(input_port)] if input_port else []
    return subprocess.Popen([sys.executable, "-m", "stylecast", name, *extra])


def run_demo(args, config: DaemonConfig) -> int:
    from stylecast.drivers.bvh.bvh_replay import ReplaySource, humanoid_motion
    from stylecast.drivers.urls import parse_url
    from stylecast.motion.bvh import read_bvh, require_frames

    from .runner import run_daemon

    clip_path = find_clip(args.clip_option or args.clip)
    if not config.out:
        config.out = [DEFAULT_OUT]
    if not config.out_input:
        config.out_input = [f"vmc://127.0.0.1:{DEFAULT_INPUT_PORT}"]
    model = config.model or DEFAULT_MODEL
    restyler = demo_restyler(model, config.device)
    clip = require_frames(read_bvh(clip_path), str(clip_path))
    source = ReplaySource(humanoid_motion(clip), clip_path.name.split(".")[0], loop=True, speed=args.speed)
    print(f"stylecast demo: replaying {clip_path} (looping) -> {', '.join(config.out)}; "
          f"Ctrl-C to stop", file=sys.stderr)
    input_port = parse_url(config.out_input[0]).port if config.out_input else None
    viewer = open_viewer(input_port) if args.view else None
    try:
        return run_daemon(config, restyler=restyler, sources=[source])
    finally:
        if viewer is not None:
            viewer.terminate()
            viewer.wait(timeout=5)
