"""`stylecast view`: argument parsing only; GL and sockets are imported when the command runs."""

from __future__ import annotations

import argparse

from stylecast.motion.errors import UserError

LAYOUT_CHOICES = ("side", "overlay")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "view", help="draw the performers of a VMC stream (window, or headless PNGs)",
        description="Listen for VMC like a marionette and draw every performer heard: restyled on --port, "
                    "the daemon's unrestyled input on --input-port, side by side or overlaid. With --snapshot "
                    "or --frames it renders headless through EGL (no display needed).")
    p.add_argument("--port", type=int, default=39539, help="UDP port of the restyled stream (default 39539)")
    p.add_argument("--bind", default="127.0.0.1",
                   help="address to listen on (default 127.0.0.1; 0.0.0.0 for every interface)")
    p.add_argument("--input-port", type=int, default=None, metavar="N",
                   help="also listen on N for the unrestyled input (e.g. 39541)")
    p.add_argument("--performers", type=int, default=1, metavar="N",
                   help="listen for N performers on PORT..PORT+N-1 (and the input ports likewise), "
                        "as the daemon sends performer k to PORT+k (default 1)")
    p.add_argument("--status", default="127.0.0.1:39570", metavar="HOST:PORT",
                   help="the daemon's control port, asked once a second for style, intensity and "
                        "restyle latency (default 127.0.0.1:39570; 'off' to not ask)")
    p.add_argument("--layout", choices=LAYOUT_CHOICES, default="side",
                   help="input and restyled side by side (default) or overlaid in two colours")
    p.add_argument("--spacing", type=float, default=1.8, metavar="M",
                   help="metres between neighbouring skeletons (default 1.8)")
    p.add_argument("--snapshot", metavar="PNG", help="render headless and write one PNG after --after seconds")
    p.add_argument("--after", type=float, default=2.0, metavar="S", help="seconds before the snapshot (default 2)")
    p.add_argument("--frames", metavar="DIR", help="render headless and write DIR/frame_00000.png ...")
    p.add_argument("--duration", type=float, default=5.0, metavar="S", help="seconds of --frames (default 5)")
    p.add_argument("--fps", type=float, default=30.0, help="headless render and --frames rate (default 30)")
    p.add_argument("--width", type=int, default=1280)
    p.add_argument("--height", type=int, default=720)
    p.add_argument("--msaa", type=int, default=None, metavar="N",
                   help="multisampling (default: 4 for --snapshot and on a GPU; 0 for --frames and "
                        "on a software renderer)")
    p.add_argument("--default-skeleton", action="store_true",
                   help="ignore the bone offsets the stream carries; draw a default humanoid")
    p.set_defaults(func=run)


def _check(args) -> None:
    for name in ("port", "input_port"):
        port = getattr(args, name)
        if port is not None and not 0 <= port <= 65535:
            raise UserError(f"--{name.replace('_', '-')} {port} is not a UDP port; use 1 to 65535, e.g. 39539")
    if not (16 <= args.width <= 8192 and 16 <= args.height <= 8192):
        raise UserError(f"--width/--height {args.width}x{args.height} is not a usable image size; use 16 to 8192")
    if not args.after >= 0 or not args.duration > 0 or not args.fps > 0 or not args.spacing >= 0:
        raise UserError("--after and --spacing must be >= 0, --duration and --fps > 0")
    if args.msaa is not None and args.msaa not in (0, 2, 4, 8):
        raise UserError(f"--msaa {args.msaa}: use 0, 2, 4 or 8")
    if not 1 <= args.performers <= 64:
        raise UserError(f"--performers {args.performers}: use 1 to 64")
    for base in (args.port, args.input_port):
        if base is not None and base and base + args.performers - 1 > 65535:
            raise UserError(f"--performers {args.performers} from port {base} runs past 65535; choose a lower port")
    if args.input_port is not None and args.input_port and args.port and (
            abs(args.input_port - args.port) < args.performers):
        raise UserError(f"the input ports {args.input_port}.. overlap the restyled ports {args.port}..; "
                        f"leave {args.performers} ports between them, "
                        f"e.g. --input-port {args.port + 2 * args.performers}")


def parse_status(value: str) -> tuple[str, int] | None:
    if value.lower() in ("off", "none", ""):
        return None
    host, sep, port = value.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) <= 65535:
        raise UserError(f"--status {value!r}: write the daemon's control port as HOST:PORT, e.g. "
                        f"127.0.0.1:39570, or 'off'")
    return host.strip("[]"), int(port)


def run(args: argparse.Namespace) -> int:
    _check(args)
    status = parse_status(args.status)
    size = (args.width, args.height)
    if args.snapshot or args.frames:
        from .headless import view_headless

        result = view_headless(port=args.port, bind=args.bind, input_port=args.input_port, after=args.after,
                               snapshot=args.snapshot, frames_dir=args.frames, duration=args.duration, size=size,
                               layout=args.layout, spacing=args.spacing, samples=args.msaa, fps=args.fps,
                               use_stream_offsets=not args.default_skeleton, performers=args.performers,
                               status=status)
        heard = ", ".join(f"{k} ({n} frames)" for k, n in result.performers.items()) or "no performer"
        written = f"{len(result.frames)} frames in {args.frames}" if args.frames else ""
        if result.snapshot:
            written = f"{written}; {result.snapshot}" if written else str(result.snapshot)
        print(f"stylecast view: wrote {written}; heard {heard}")
        if result.ignored:
            print("stylecast view: ignored " + ", ".join(f"{n} {r}" for r, n in sorted(result.ignored.items())))
        return 0
    from .headless import listen_all
    from .window import run_window

    run_window(size, args.layout, args.spacing, lambda viewer: listen_all(
        viewer, args.port, args.bind, args.input_port, args.performers, not args.default_skeleton, status),
        msaa=args.msaa)
    return 0
