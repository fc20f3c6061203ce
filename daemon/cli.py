"""``stylecast serve``, ``stylecast demo`` and ``stylecast repair``.

Heavy imports (numpy, scipy, torch through the model) happen inside the commands so
``stylecast --help`` stays fast.
"""

from __future__ import annotations

import argparse
import sys


def register(subparsers) -> None:
    p = subparsers.add_parser("serve", help="run the live restyling daemon",
                              description="Restyle live mocap: sources in, VMC out. Flags override --config.")
    _daemon_flags(p)
    p.add_argument("--source", action="append", default=None, metavar="URL",
                   help="bvh:///clip.bvh?loop=1&speed=1.0&name=alice, vmc://HOST:PORT, serial://...; "
                        "repeat for several performers")
    p.set_defaults(func=cmd_serve)

    d = subparsers.add_parser("demo", help="replay a Bandai clip through the daemon to 127.0.0.1:39539",
                              description="No hardware needed: replays a recorded clip (looping) through the "
                                          "daemon with the shipped model and sends VMC to 127.0.0.1:39539.")
    d.add_argument("clip", nargs="?", default=None, help="a BVH file (default: a dataset-2 normal walk)")
    d.add_argument("--clip", dest="clip_option", default=None, metavar="PATH", help="same as CLIP")
    d.add_argument("--no-view", dest="view", action="store_false",
                   help="do not open the viewer window (it opens when stylecast[viewer] and a display are there)")
    d.add_argument("--speed", type=float, default=1.0, help="replay speed (default 1.0)")
    _daemon_flags(d)
    d.set_defaults(func=cmd_demo)

    r = subparsers.add_parser("repair", help="fix the frame count of a BVH recording cut short (kill -9)")
    r.add_argument("file", help="the .bvh file to repair in place")
    r.set_defaults(func=cmd_repair)


def _daemon_flags(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", default=None, metavar="FILE", help="TOML file with the same settings")
    p.add_argument("--out", action="append", default=None, metavar="URL",
                   help="vmc://HOST:PORT receiver (repeat to fan out); performer k goes to PORT+k")
    p.add_argument("--out-input", dest="out_input", action="append", default=None, metavar="URL",
                   help="vmc://HOST:PORT for the unrestyled input (before/after views)")
    p.add_argument("--record", default=None, metavar="FILE.bvh", help="record the restyled humanoid motion")
    from .latency import LATENCY_PRESETS  # small: no numpy, no torch

    p.add_argument("--latency", default=None, choices=tuple(LATENCY_PRESETS),
                   help="hop and delay preset: " + "; ".join(f"{k}: {v.about}" for k, v in LATENCY_PRESETS.items())
                        + "; --hop and --delay override it")
    p.add_argument("--hop", type=int, default=None, help="frames between motion words, 1..60 (default: the preset's)")
    p.add_argument("--delay", type=int, default=None,
                   help="output delay in frames, >= hop (default: the preset's; raised when the model is too slow)")
    p.add_argument("--decay", type=float, default=None, help="seam offset time constant in frames")
    p.add_argument("--crossfade", type=float, default=None, help="seconds of every fade (default 0.5)")
    p.add_argument("--intensity", type=float, default=None, help="0..1 (default 1)")
    p.add_argument("--bypass", action="store_true", default=None, help="start in bypass (pass-through)")
    p.add_argument("--model", default=None, help="model name or checkpoint path (default normal2exhausted); "
                                                 "'identity' runs without a model")
    p.add_argument("--direction", default=None, help="restyling direction of the model")
    p.add_argument("--style", default=None, metavar="NAME[:W,NAME:W...]",
                   help="style of a multi-style model, or a mix such as elderly:0.5,youthful:0.5")
    p.add_argument("--performer-style", dest="performer_style", default=None, metavar="NAME|auto",
                   help="the style the performers move in (default normal), for a multi-style model: its share "
                        "of a style mix is the input as performed; auto reads it from each word they send")
    p.add_argument("--control", default=None, metavar="HOST:PORT",
                   help="OSC control port (default 127.0.0.1:39570; 'off' disables)")
    p.add_argument("--allow", action="append", default=None, metavar="ADDR",
                   help="source address or network allowed on the control port (default loopback)")
    p.add_argument("--status-interval", dest="status_interval", type=float, default=None,
                   help="seconds between status lines (default 5)")
    p.add_argument("--unbundled", dest="bundled", action="store_false", default=None,
                   help="send one OSC message per datagram (for receivers without bundle support)")
    p.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    p.add_argument("--feet", default=None, metavar="auto|input|stance|path",
                   help="planted feet on the input's own ankles (input) or where the restyled legs stand "
                        "(stance: keeps a style's stance), or on the input's ankles with the feet in the air on "
                        "the input's own path too (path); default auto: the model's own (the pair model input, "
                        "the multistyle model stance, path for elderly or exhausted)")
    p.add_argument("--pace", default=None, metavar="style|input",
                   help="the avatar covers ground at the target style's pace (style, the default: it falls "
                        "behind a performer who walks on, and walking back takes it back) or at the "
                        "performer's own (input: it stays where the performer is)")
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes to spread the performers over, each with its own model "
                        "(default 0: one per core, at most one per performer)")
    p.add_argument("--device", default=None,
                   help="where the model runs: auto (CUDA when present, the default), cpu, cuda or cuda:N")


_CONFIG_KEYS = ("source", "out", "out_input", "record", "latency", "hop", "delay", "decay", "crossfade", "intensity",
                "bypass", "model", "direction", "style", "control", "allow", "status_interval", "bundled", "duration",
                "device", "workers", "feet", "pace")


def _config(args):
    from .config import build_config, load_config

    flags = {k: getattr(args, k, None) for k in _CONFIG_KEYS}
    return build_config(load_config(args.config), flags)


def _setup_logging() -> None:
    import logging

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s", datefmt="%H:%M:%S",
                        stream=sys.stderr)


def cmd_serve(args) -> int:
    from .runner import run_daemon
    from .workers import run_workers

    _setup_logging()
    config = _config(args)
    if config.processes > 1:
        return run_workers(config)
    return run_daemon(config)


def cmd_demo(args) -> int:
    from .demo import run_demo

    _setup_logging()
    return run_demo(args, _config(args))


def cmd_repair(args) -> int:
    from stylecast.drivers.bvh.bvh_recorder import repair_bvh

    frames, dropped = repair_bvh(args.file)
    print(f"{args.file}: {frames} frames kept, {dropped} bytes of a cut last frame dropped; frame count fixed")
    return 0
