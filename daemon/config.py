"""Daemon settings: defaults, then a TOML file (``--config``), then flags (flags win).

The TOML file uses the flag names with underscores, for example::

    source = ["bvh:///clips/walk.bvh?loop=1"]
    out = ["vmc://127.0.0.1:39539"]
    latency = "low"
    intensity = 0.8
    model = "normal2exhausted"
    control = "127.0.0.1:39570"
    allow = ["127.0.0.1", "192.168.1.20"]

Unknown keys and wrong types are refused with one sentence (a typo must not be ignored).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path

from stylecast.motion.clock import OUTPUT_FPS
from stylecast.motion.errors import UserError

from .control import DEFAULT_ALLOW, DEFAULT_CONTROL_PORT

FPS = OUTPUT_FPS  # the one definition lives in motion.clock


@dataclass
class DaemonConfig:
    source: list[str] = field(default_factory=list)
    out: list[str] = field(default_factory=list)
    out_input: list[str] = field(default_factory=list)
    record: str = ""
    latency: str = "default"  # a preset of hop and delay (daemon.latency.LATENCY_PRESETS)
    hop: int = 0  # frames; 0 = the latency preset's
    delay: int = 0  # frames; 0 = the preset's when the hop is too, else the hop (the minimum)
    decay: float = -1.0  # seam offset time constant in frames; -1 = the blender's default
    crossfade: float = 0.5  # seconds of every pass-through <-> restyled fade
    intensity: float = 1.0
    bypass: bool = False
    model: str = "normal2exhausted"
    direction: str = ""
    style: str = ""  # a multi-style model's style or mix "NAME:W,NAME:W"; "" = the model's own
    # The style the performers move in, for a multi-style model (its share of a mix is the input
    # as performed); "" = the neutral style.
    performer_style: str = ""
    control: str = f"127.0.0.1:{DEFAULT_CONTROL_PORT}"  # "off" disables it
    allow: list[str] = field(default_factory=lambda: list(DEFAULT_ALLOW))
    status_interval: float = 5.0
    bundled: bool = True
    duration: float = 0.0  # seconds; 0 = until stopped
    device: str = "auto"  # where the model runs: auto (CUDA when present), cpu, cuda[:N]
    workers: int = 0  # processes the performers are spread over (daemon.workers); 0 = one per core
    feet: str = "auto"  # where planted feet go (motion.footlock.FEET): auto (the model's), input, stance
    pace: str = "style"  # whose pace the avatar covers ground at (motion.footlock.PACE_CHOICES)

    def validate(self) -> "DaemonConfig":
        from .latency import LATENCY_PRESETS

        preset = LATENCY_PRESETS.get(self.latency)
        if preset is None:
            raise UserError(f"--latency {self.latency!r} is not a preset; use one of {', '.join(LATENCY_PRESETS)}")
        if self.hop == 0:  # the preset's hop, and its delay unless one was given
            self.hop = preset.hop
            self.delay = self.delay or preset.hop + preset.slack - 1
        if not 1 <= self.hop <= 60:
            raise UserError(f"--hop {self.hop} is out of range; use 1 to 60 frames")
        if self.delay and self.delay < self.hop:
            raise UserError(f"--delay {self.delay} is shorter than the hop ({self.hop}); use at least the hop")
        if not 0.0 <= self.intensity <= 1.0:
            raise UserError(f"--intensity {self.intensity} is out of range; use 0 to 1")
        if not 0.0 <= self.crossfade <= 60.0:
            raise UserError(f"--crossfade {self.crossfade} is out of range; use 0 to 60 seconds")
        if self.status_interval <= 0:
            raise UserError("--status-interval must be positive")
        from stylecast.motion.footlock import check_feet, check_pace

        check_feet(self.feet)
        check_pace(self.pace)
        if not 0 <= self.workers <= 256:
            raise UserError(f"--workers {self.workers} is out of range; use 1 to 256 processes, or 0 for one per core")
        if self.style:
            from stylecast.models.styles import parse_mix

            parse_mix(self.style)  # unknown names: one sentence before any model or source is opened
        if self.performer_style:
            from stylecast.models.styles import check_performer_style

            check_performer_style(self.performer_style)
        from stylecast.models.device import check_device_name

        self.device = check_device_name(self.device)
        self._check_ports()
        return self

    def _check_ports(self) -> None:
        """A port the daemon listens on (a ``vmc://`` source, the control port) named twice,
        or also as where it sends: one sentence before any socket is opened. (A second
        source on a port failed to bind only after the first had started; an output into a
        source's own port would read back what the daemon sends.)"""
        from stylecast.drivers.urls import parse_url

        def same_machine(host: str) -> str:
            return "local" if host in ("", "localhost", "127.0.0.1", "::1", "0.0.0.0", "::") else host

        listening: dict = {}  # port 0: each its own port, picked by the system
        control = self.control_address()
        if control is not None and control[1]:
            listening[(same_machine(control[0]), control[1])] = f"--control {self.control}"
        for text in self.source:
            url = parse_url(text)
            if url.scheme != "vmc" or not url.port:
                continue
            key = (same_machine(url.host), url.port)
            if key in listening:
                raise UserError(f"--source {text} listens on the port of {listening[key]}; give each source and "
                                f"the control port a port of its own")
            listening[key] = f"--source {text}"
        for option, texts in (("--out", self.out), ("--out-input", self.out_input)):
            for text in texts:
                url = parse_url(text)
                key = (same_machine(url.host), url.port)
                if url.port is not None and key in listening:
                    raise UserError(f"{option} {text} sends to the port of {listening[key]}, so the daemon would "
                                    f"read back what it sends; send to another port")

    @property
    def processes(self) -> int:
        """Worker processes ``serve`` runs: ``workers`` (0: one per core this process may
        use), never more than there are performers."""
        import os

        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
        return max(1, min(self.workers or cores, len(self.source)))

    @property
    def crossfade_frames(self) -> int:
        return max(1, round(self.crossfade * FPS))

    def control_address(self) -> tuple[str, int] | None:
        if self.control.lower() in ("off", "none", "", "0"):
            return None
        host, _, port = self.control.rpartition(":")
        try:
            return (host.strip("[]") or "127.0.0.1", int(port))
        except ValueError:
            raise UserError(f"--control {self.control!r} must be HOST:PORT such as 127.0.0.1:{DEFAULT_CONTROL_PORT}, "
                            f"or off") from None


def _check_type(name: str, value, default):
    kind = type(default)
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if kind is list:
        if isinstance(value, str):
            return [value]
        if isinstance(value, list) and all(isinstance(v, str) for v in value):
            return value
    elif isinstance(value, kind) and not (kind is int and isinstance(value, bool)):
        return value
    raise UserError(f"config key {name} = {value!r} has the wrong type; expected {kind.__name__}")


def load_config(path: str | Path | None) -> dict:
    """The TOML table as validated DaemonConfig field values."""
    if not path:
        return {}
    path = Path(path)
    try:
        table = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise UserError(f"cannot read config file {path}: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"config file {path} is not valid TOML: {exc}") from None
    defaults = DaemonConfig()
    known = {f.name for f in fields(DaemonConfig)}
    out = {}
    for key, value in table.items():
        name = key.replace("-", "_")
        if name not in known:
            raise UserError(f"config file {path}: unknown key {key!r} (known keys: {', '.join(sorted(known))})")
        out[name] = _check_type(name, value, getattr(defaults, name))
    return out


def build_config(file_values: dict, flag_values: dict) -> DaemonConfig:
    """Defaults < config file < flags; a flag left at None (not given) does not override."""
    cfg = DaemonConfig(**file_values)
    for key, value in flag_values.items():
        if value is None or (isinstance(value, list) and not value):
            continue
        setattr(cfg, key, value)
    return cfg.validate()
