"""The control commands: ONE table from OSC address to a typed command.

python-osc's dispatcher habit: a table maps each address to what handles it. Here one
``Command`` row holds both halves, how a message's arguments become a typed value
(``parse``, run on the control thread, never raising) and what that value does to the
daemon (``apply``, run by the output loop at the start of a tick), so the parser and the
daemon can never disagree about which commands exist or what their values mean. The
README's table of addresses is this table.

    /stylecast/intensity  0..1, slerp input -> restyled
    /stylecast/bypass     pass the input through (1) or restyle (0)
    /stylecast/crossfade  length of every fade from the next one on
    /stylecast/direction  e.g. "a2b" / "b2a" for the loaded model
    /stylecast/model      loaded in the background, then swapped
    /stylecast/style      a style of a multi-style model; weight < 1 leaves the rest to normal
    /stylecast/mix        a weighted style mix
    /stylecast/calibrate  tracker sources: calibrate on the next frames
    /stylecast/status     replied to the sender (see status.py)

Each row's ``usage`` says its arguments; a command with wrong ones is refused with that
sentence, logged once per address (then counted), as ``usage_line`` words it.

Values a hostile or broken sender could use to do harm are refused here, not clamped
later: non-finite numbers, crossfades beyond a minute, strings beyond 512 bytes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

from stylecast.motion.clock import OUTPUT_FPS as FPS
from stylecast.models.styles import NEUTRAL
from stylecast.motion.errors import UserError

PREFIX = "/stylecast/"
MAX_CROSSFADE_S = 60.0
MAX_NAME = 512
MAX_MIX = 16  # name/weight pairs in one /stylecast/mix


@dataclass(frozen=True)
class Command:
    name: str
    parse: Callable[[tuple], Any]  # arguments -> value, or None when they are wrong
    apply: Callable  # (daemon, value, sessions, reply_to) -> None
    per_performer: bool = False  # a trailing string argument names one performer
    usage: str = "no arguments"  # its OSC arguments (type tag, meaning), for the refusal's sentence

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


def _without_performer(args: tuple) -> tuple:
    """A style command's own arguments: a trailing performer name is parse_command's."""
    return args[:-1] if len(args) % 2 == 1 and len(args) > 1 and isinstance(args[-1], str) else args


def _weight(value) -> float | None:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    return float(value) if ok and 0.0 <= value <= 1e6 else None


def _style(args: tuple) -> tuple | None:
    """NAME [WEIGHT]: ((name, w), (NEUTRAL, 1 - w)); names are checked when applied,
    against the model's own styles, so a typo gets the sentence listing them."""
    if len(args) >= 2 and isinstance(args[-1], str):
        args = args[:-1]  # the performer: parse_command's
    if not 1 <= len(args) <= 2 or _name(args) is None:
        return None
    w = _weight(args[1]) if len(args) == 2 else 1.0
    if w is None or w > 1.0:
        return None
    return ((args[0], w),) + (((NEUTRAL, 1.0 - w),) if w < 1.0 else ())


def _mix(args: tuple) -> tuple | None:
    """NAME W NAME W ...: ((name, w), ...); weights are normalised when applied."""
    args = _without_performer(args)
    if not args or len(args) % 2 or len(args) > 2 * MAX_MIX:
        return None
    pairs = tuple(zip(args[0::2], args[1::2]))
    if any(_name((n,)) is None or _weight(w) is None for n, w in pairs):
        return None
    return tuple((n, _weight(w)) for n, w in pairs)


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


def _set_style(daemon, value, sessions, reply_to) -> None:
    daemon.set_style(value, sessions)


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
    Command("intensity", _unit, _set_intensity, True, "f value (0 to 1) [s performer]"),
    Command("bypass", _flag, _set_bypass, True, "i 0 or 1 (f, T and F too) [s performer]"),
    Command("crossfade", _seconds, _set_crossfade, usage=f"f seconds (0 to {MAX_CROSSFADE_S:g})"),
    Command("direction", _name, _set_direction, usage="s name, such as a2b or b2a"),
    Command("model", _name, _load_model, usage="s a shipped model's name or a .safetensors path"),
    Command("style", _style, _set_style, True, "s style [f weight (0 to 1)] [s performer]"),
    Command("mix", _mix, _set_style, True, f"s style f weight (0 or more) [s style f weight ...] (up to {MAX_MIX} "
                                            f"pairs) [s performer]"),
    Command("calibrate", _nothing, _calibrate, True, "[s performer]"),
    Command("status", _nothing, _status),
)}
BY_NAME: dict[str, Command] = {c.name: c for c in COMMANDS.values()}


def usage_line(address: str, reason: str) -> str:
    """The one sentence for a command ``parse_command`` refused for ``reason``."""
    if reason == "unknown_address":
        return f"unknown address {address[:80]!r}; the known ones are {', '.join(COMMANDS)}"
    return f"{address} takes {COMMANDS[address].usage}; ignored"


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
