"""The control commands: ONE table from OSC address to a typed command.

python-osc's dispatcher habit: a table maps each address to what handles it. Here one
``Command`` row holds both halves, how a message's arguments become a typed value
(``parse``, run on the control thread, never raising) and what that value does to the
daemon (``apply``, run by the output loop at the start of a tick), so the parser and the
daemon can never disagree about which commands exist or what their values mean. The
README's table of addresses is this table.

    /stylecast/intensity  f value [s performer]   0..1, slerp input -> restyled
    /stylecast/bypass     i 0|1   [s performer]   (f, T and F accepted too)
    /stylecast/crossfade  f seconds               length of every fade from the next one on
    /stylecast/direction  s name                  e.g. "a2b" / "b2a" for the loaded model
    /stylecast/model      s name-or-path          loaded in the background, then swapped
    /stylecast/calibrate  [s performer]           tracker sources: calibrate on the next frames
    /stylecast/status                             replied to the sender (see status.py)

Values a hostile or broken sender could use to do harm are refused here, not clamped
later: non-finite numbers, crossfades beyond a minute, strings beyond 512 bytes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

from stylecast.motion.clock import OUTPUT_FPS as FPS
from stylecast.motion.errors import UserError

PREFIX = "/stylecast/"
MAX_CROSSFADE_S = 60.0
MAX_NAME = 512


@dataclass(frozen=True)
class Command:
    name: str
    parse: Callable[[tuple], Any]  # arguments -> value, or None when they are wrong
    apply: Callable  # (daemon, value, sessions, reply_to) -> None
    per_performer: bool = False  # a trailing string argument names one performer

    @property
    def address(self) -> str:
        return PREFIX + self.name


# -- parsing: arguments -> typed value (None = bad arguments) --------------------------

def _number(args: tuple) -> float | None:
    first = args[0] if args else None
    if isinstance(first, (int, float)) and not isinstance(first, bool) and math.isfinite(first):
        return float(first)
    return None


def _unit(args: tuple) -> float | None:
    # +inf/-inf/NaN are refused by _number, never clamped into range: they mean a broken sender.
    value = _number(args)
    return None if value is None else min(1.0, max(0.0, value))


def _flag(args: tuple) -> bool | None:
    first = args[0] if args else None
    if isinstance(first, bool):
        return first
    if isinstance(first, (int, float)):
        return first != 0
    return None


def _seconds(args: tuple) -> float | None:
    value = _number(args)
    return value if value is not None and 0.0 <= value <= MAX_CROSSFADE_S else None


def _name(args: tuple) -> str | None:
    first = args[0] if args else None
    return first if isinstance(first, str) and 0 < len(first) <= MAX_NAME else None


def _nothing(args: tuple) -> bool:
    return True


# -- applying: typed value -> daemon state (output loop, start of a tick) --------------

def _set_intensity(daemon, value, sessions, reply_to) -> None:
    for s in sessions:
        s.intensity = float(value)


def _set_bypass(daemon, value, sessions, reply_to) -> None:
    for s in sessions:
        s.set_bypass(bool(value))


def _set_crossfade(daemon, value, sessions, reply_to) -> None:
    # Every session's blender reads this one settings object (engine.Daemon.settings), so
    # the next fade of every performer has the new length.
    daemon.settings.crossfade_frames = max(1, round(float(value) * FPS))


def _set_direction(daemon, value, sessions, reply_to) -> None:
    daemon.set_direction(str(value))


def _load_model(daemon, value, sessions, reply_to) -> None:
    daemon.load_model_async(str(value))


def _calibrate(daemon, value, sessions, reply_to) -> None:
    able = [s for s in sessions if callable(getattr(s.source, "calibrate", None))]
    if not able:
        raise UserError("no tracker source to calibrate; /stylecast/calibrate applies to vmc:// tracker "
                        "and serial:// sources")
    for s in able:
        s.source.calibrate()


def _status(daemon, value, sessions, reply_to) -> None:
    daemon.reply_status(reply_to)


COMMANDS: dict[str, Command] = {c.address: c for c in (
    Command("intensity", _unit, _set_intensity, per_performer=True),
    Command("bypass", _flag, _set_bypass, per_performer=True),
    Command("crossfade", _seconds, _set_crossfade),
    Command("direction", _name, _set_direction),
    Command("model", _name, _load_model),
    Command("calibrate", _nothing, _calibrate, per_performer=True),
    Command("status", _nothing, _status),
)}
BY_NAME: dict[str, Command] = {c.name: c for c in COMMANDS.values()}


def parse_command(address: str, tags: str, args: tuple):
    """A decoded message -> (command name, value, performer or None), or (None, reason)."""
    command = COMMANDS.get(address)
    if command is None:
        return (None, "unknown_address")
    value = command.parse(args)
    if value is None:
        return (None, "bad_arguments")
    performer = None
    if command.per_performer and args and isinstance(args[-1], str) and (len(args) >= 2 or command.parse is _nothing):
        performer = args[-1]
    if command.parse is _nothing:
        value = None
    return (command.name, value, performer)


def apply_command(daemon, name: str, value, performer: str | None = None, reply_to=None) -> None:
    """Apply one parsed command to ``daemon`` (UserError, one sentence, when it cannot)."""
    command = BY_NAME.get(name)
    if command is None:
        raise UserError(f"unknown control command {name!r}; known: {', '.join(sorted(BY_NAME))}")
    sessions = [s for s in daemon.sessions if performer in (None, s.performer)]
    if performer is not None and not sessions:
        raise UserError(f"no performer called {performer!r}")
    command.apply(daemon, value, sessions, reply_to)
