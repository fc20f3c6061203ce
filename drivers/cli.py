"""`stylecast emulate`: replay a BVH clip as a VIVE-style tracker set (serial or VMC)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "emulate", help="replay a BVH clip as VIVE-style tracker poses over serial or VMC",
        description="Replays a BVH clip as the tracker poses a VIVE setup would report (10 points: HMD, "
                    "controllers, waist, elbows, knees, feet; 6 points: head, hands, waist, feet), to a "
                    "serial device in stylecast's tracker framing (docs/SERIAL_FRAMING.md) or to a VMC "
                    "receiver as /VMC/Ext/Hmd|Con|Tra/Pos messages.")
    p.add_argument("--bvh", type=Path, required=True, metavar="CLIP", help="BVH file (.bvh or .bvh.gz)")
    p.add_argument("--to", required=True, metavar="URL",
                   help="serial:///dev/pts/N?baud=921600 (or any pyserial URL) or vmc://HOST:PORT")
    p.add_argument("--points", type=int, default=10, choices=(10, 6), help="tracker set (default 10)")
    p.add_argument("--noise", type=float, default=0.0, metavar="MM",
                   help="Gaussian position noise, standard deviation in millimetres (default 0)")
    p.add_argument("--rot-noise", type=float, default=0.0, metavar="DEG",
                   help="Gaussian rotation noise, degrees (default 0)")
    p.add_argument("--drop", type=float, default=0.0, metavar="RATE",
                   help="fraction of samples lost, in bursts like occlusions (default 0)")
    p.add_argument("--seed", type=int, default=0, help="random seed for noise and dropouts (default 0)")
    p.add_argument("--speed", type=float, default=1.0, help="playback rate (default 1: real time)")
    p.add_argument("--rate", type=float, default=None, metavar="HZ",
                   help="tracker sample rate (default: the clip's frame rate; VIVE trackers report 90-250 Hz)")
    p.add_argument("--tpose", type=float, default=0.0, metavar="S",
                   help="stand S seconds in a T-pose before the clip, for calibrate=tpose (default 0)")
    p.add_argument("--loop", action="store_true", help="replay forever")
    p.add_argument("--frames", type=int, default=None, metavar="N", help="stop after N frames")
    p.set_defaults(func=run_emulate)


def run_emulate(args) -> int:
    import sys

    from stylecast.motion.errors import UserError

    from stylecast.drivers.trackers.emulator import Emulator, emulate_trackers, load_humanoid, with_tpose

    if not args.bvh.is_file():
        raise UserError(f"--bvh {args.bvh} does not exist; give the path of a .bvh or .bvh.gz file")
    if args.frames is not None and args.frames < 1:
        raise UserError(f"--frames {args.frames} must be at least 1")
    if not 0.0 <= args.rot_noise <= 90.0:
        raise UserError(f"--rot-noise {args.rot_noise} is out of range; give degrees between 0 and 90")
    motion = with_tpose(load_humanoid(args.bvh), args.tpose)
    recording = emulate_trackers(motion, args.points, noise_mm=args.noise, rot_noise_deg=args.rot_noise,
                                 drop=args.drop, seed=args.seed, speed=args.speed, rate=args.rate)
    sink = open_tracker_sink(args.to)
    rate = 1.0 / (recording.timestamps[1] - recording.timestamps[0]) if len(recording) > 1 else motion.fps
    print(f"emulating {args.points} trackers from {args.bvh.name} ({len(recording)} frames at "
          f"{rate:.4g} Hz) to {args.to}; Ctrl-C stops", file=sys.stderr)
    emulator = Emulator(recording)
    try:
        emulator.run(sink, loop=args.loop, max_frames=args.frames)
    finally:
        sink.close()
        stats = sink.stats
        extra = ""
        if hasattr(stats, "disconnects"):
            extra = (f"; {stats.disconnects} disconnects, {stats.reconnects} reconnects, "
                     f"{stats.extra.get('dropped_bytes', 0)} bytes dropped")
        print(f"sent {emulator.frames_sent} frames{extra}", file=sys.stderr)
    return 0


def open_tracker_sink(url: str, clock=None):
    """``vmc://HOST:PORT`` -> VmcTrackerSink; ``serial://...``, any other pyserial URL or a
    device path -> SerialTrackerSink (pyserial's own schemes are pyserial's to parse)."""
    from stylecast.drivers.serial.serial_trackers import SerialTrackerSink
    from stylecast.drivers.urls import parse_url
    from stylecast.drivers.vmc.vmc_out import VmcTrackerSink
    from stylecast.motion.errors import UserError

    text = str(url).strip()
    if "://" not in text and not text.startswith("/"):
        raise UserError(f"--to {text!r} is not an output; give serial:///dev/pts/N?baud=921600 or vmc://HOST:PORT")
    if "://" in text and parse_url(text).scheme == "vmc":
        return VmcTrackerSink(text)
    sink = SerialTrackerSink(text, clock=clock)
    if not sink.connected:  # at start a missing device is a typo, not an unplugged cable
        problem = sink.stats.last_error
        sink.close()
        raise UserError(f"cannot open serial output {text} ({problem}); check the device path "
                        f"(for a pseudo-terminal: the /dev/pts/N its other end printed)")
    return sink
