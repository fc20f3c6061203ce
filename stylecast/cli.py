"""The `stylecast` command. Each subsystem registers its own subcommands in its `cli`
module; heavy imports (torch, GL) happen inside the command functions, so `--help` is fast."""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from stylecast.motion.errors import UserError

# Modules that define `register(subparsers)`; a subsystem that is not installed or not
# written yet simply contributes no commands.
COMMAND_MODULES = (
    "stylecast.motion.cli",
    "stylecast.models.cli",
    "stylecast.daemon.cli",
    "stylecast.drivers.cli",
    "stylecast.viewer.cli",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="stylecast", description="Live motion restyling over VMC/OSC.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name == name:
                continue
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f"stylecast: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # Whoever read the output has gone (`stylecast info F.bvh | head -3`): stop quietly,
        # as Unix tools do, rather than with a traceback (and another when Python flushes
        # stdout on exit, hence stdout pointed at /dev/null first).
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + 13  # what a shell reports for a tool stopped by SIGPIPE (13)


if __name__ == "__main__":
    sys.exit(main())
