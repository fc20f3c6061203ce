"""Endpoint URLs (``bvh:///clip.bvh?loop=1``, ``vmc://127.0.0.1:39539``), parsed once.

pyserial's ``serial_for_url`` idea: a scheme picks the module, the query string carries
options, and an option nobody declared is refused instead of silently ignored (a typo
such as ``lop=1`` must not replay once and stop). Every refusal is one UserError sentence.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from urllib.parse import parse_qsl, unquote, urlsplit

from stylecast.motion.errors import UserError

_TRUE = {"1", "true", "yes", "on"}
_FALSE = {"0", "false", "no", "off"}


@dataclass(frozen=True)
class EndpointUrl:
    text: str
    scheme: str
    host: str
    port: int | None
    path: str
    options: dict
    netloc: str = ""  # the authority as written (hostname() lowercases it; COM3 must stay COM3)

    def take(self, spec: dict[str, tuple[type, object]]) -> dict:
        """Options converted per ``spec`` {name: (type, default)}; unknown names refused."""
        unknown = sorted(set(self.options) - set(spec))
        if unknown:
            known = ", ".join(sorted(spec)) or "none"
            raise UserError(f"{self.text}: unknown option {', '.join(unknown)} for {self.scheme}:// "
                            f"(known options: {known})")
        out = {}
        for name, (kind, default) in spec.items():
            raw = self.options.get(name)
            out[name] = default if raw is None else _convert(self.text, name, raw, kind)
        return out

    def address(self, default_host: str = "127.0.0.1") -> tuple[str, int]:
        if self.port is None:
            raise UserError(f"{self.text}: give a port, as in {self.scheme}://127.0.0.1:39539")
        return (self.host or default_host, self.port)


def _convert(text: str, name: str, raw: str, kind: type):
    try:
        if kind is bool:
            low = raw.lower()
            if low in _TRUE:
                return True
            if low in _FALSE:
                return False
            raise ValueError(raw)
        return kind(raw)
    except ValueError:
        want = {bool: "0 or 1", int: "an integer", float: "a number"}.get(kind, kind.__name__)
        raise UserError(f"{text}: option {name}={raw!r} must be {want}") from None


def parse_url(text: str) -> EndpointUrl:
    """Parse an endpoint URL; a bare path to a .bvh file counts as ``bvh://``."""
    text = str(text).strip()
    if "://" not in text:
        if text.lower().endswith((".bvh", ".bvh.gz")):
            return EndpointUrl(text, "bvh", "", None, str(Path(text)), {})
        raise UserError(f"{text!r} is not an endpoint URL; write it as scheme://..., "
                        f"for example bvh:///path/clip.bvh or vmc://127.0.0.1:39539")
    parts = urlsplit(text)
    scheme = parts.scheme.lower()
    options: dict[str, str] = {}
    for key, value in parse_qsl(parts.query, keep_blank_values=True):
        if key in options:
            raise UserError(f"{text}: option {key} is given twice")
        options[key] = value
    try:
        port = parts.port
    except ValueError:
        raise UserError(f"{text}: the port must be a number between 0 and 65535") from None
    host = parts.hostname or ""
    # bvh://clips/a.bvh (relative) and bvh:///abs/a.bvh (absolute) are both accepted.
    path = unquote(parts.path)
    if scheme in ("bvh", "file") and parts.netloc:
        path = unquote(parts.netloc) + path
        host, port = "", None
    return EndpointUrl(text, scheme, host, port, path, options, unquote(parts.netloc))


def parse_vmc_url(url: str, allowed_options=(), default_host: str = "127.0.0.1") -> tuple[str, int, dict[str, str]]:
    """``vmc://HOST:PORT?opt=value`` -> (host, port, options given), through the one
    grammar above (duplicate and unknown options refused); UserError on anything wrong."""
    parsed = parse_url(url)
    if parsed.scheme != "vmc" or parsed.path not in ("", "/"):
        raise UserError(f"bad VMC address {url!r}: write it as vmc://HOST:PORT, for example vmc://127.0.0.1:39539")
    if parsed.port is None:
        raise UserError(f"VMC address {url!r} has no port: add one, as in vmc://127.0.0.1:39539")
    given = parsed.take({name: (str, None) for name in allowed_options})
    return parsed.host or default_host, parsed.port, {k: v for k, v in given.items() if v is not None}
