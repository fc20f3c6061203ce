"""OSC 1.0 packets for the VMC drivers: a strict decoder, small encoders, ``vmc://`` URLs.

Why a decoder of our own instead of python-osc's ``OscBundle``/``OscMessage`` (which the
tests still use as the reference for what a packet means):

* python-osc 1.10.2 loops forever on a bundle element whose size is negative (the index
  steps back onto the same size field) and recurses once per nesting level, so one
  hostile datagram hangs or crashes a receiver; it also logs a warning per unknown type
  tag, which a flood turns into a log flood.
* a VMC receiver must say *why* it dropped a packet (counters by reason), which needs
  the decoder to classify errors rather than raise one generic ParseError.
* measured (bench/bench_vmc.py): python-osc parses one VMC frame (25 messages, two
  bundles) in about 155 us; this decoder, which caches addresses and one compiled
  ``struct.Struct`` plan per type-tag string, takes about 60 us.

Decoding is strict where a sloppy packet hints at a framing bug (non-zero padding,
trailing bytes, bad element sizes) and tolerant where the protocol asks (extra trailing
arguments are the caller's to ignore). It never raises on bad input: problems are
reported through an ``on_error(reason)`` callback and the bad part is skipped.

Reasons (stable strings, used as counter keys): ``empty``, ``not_osc``, ``truncated``,
``bad_padding``, ``bad_address``, ``bad_string``, ``bad_type_tag``, ``trailing_bytes``,
``bad_bundle_header``, ``bad_element_size``, ``oversized_element``, ``nested_bundle``.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence

from stylecast.motion.errors import UserError

BUNDLE_TAG = b"#bundle\x00"
IMMEDIATE = 1  # OSC time tag 0x0000000000000001: "process immediately"
# Ethernet MTU 1500 minus IPv4 (20) and UDP (8) headers: the largest datagram that is
# never fragmented on a LAN. VMC.md asks for bundles <= 1500 bytes; this satisfies it.
DEFAULT_MAX_DATAGRAM = 1472

_INT = struct.Struct(">i")
_TIMETAG = struct.Struct(">Q")
# Fixed-size argument types: struct code per OSC type tag.
_FIXED = {"i": "i", "f": "f", "h": "q", "d": "d", "t": "Q", "c": "i", "r": "I", "m": "4s"}
_CONSTANT = {"T": True, "F": False, "N": None, "I": float("inf")}
_MAX_PLANS = 512  # bound the type-tag cache: random tags from a fuzzer must not grow it


class _Bad(Exception):
    """Internal: one element failed to decode for ``reason``."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


Message = tuple[str, str, tuple]  # (address, type tags without the comma, arguments)


# ----------------------------------------------------------------------------- encoding

def osc_string(s: str | bytes) -> bytes:
    """An OSC-string: UTF-8, NUL-terminated, padded with NULs to a multiple of 4."""
    b = s.encode("utf-8") if isinstance(s, str) else bytes(s)
    return b + b"\x00" * (4 - len(b) % 4)


def encode_message(address: str, *args: str | int | float) -> bytes:
    """Encode one message with s/i/f arguments (the cold path; hot paths precompute)."""
    tags, body = [","], []
    for a in args:
        if isinstance(a, str):
            tags.append("s")
            body.append(osc_string(a))
        elif isinstance(a, (int,)) and not isinstance(a, bool):
            tags.append("i")
            body.append(_INT.pack(a))
        elif isinstance(a, float):
            tags.append("f")
            body.append(struct.pack(">f", a))
        else:
            raise TypeError(f"OSC argument {a!r} must be str, int or float")
    return osc_string(address) + osc_string("".join(tags)) + b"".join(body)


def encode_bundle(elements: Sequence[bytes], timetag: int = IMMEDIATE) -> bytes:
    parts = [BUNDLE_TAG, _TIMETAG.pack(timetag)]
    for e in elements:
        parts.append(_INT.pack(len(e)))
        parts.append(e)
    return b"".join(parts)


def group_for_bundles(sizes: Sequence[int], max_datagram: int = DEFAULT_MAX_DATAGRAM) -> list[list[int]]:
    """Greedy, order-preserving split of message indices into bundles of at most
    ``max_datagram`` bytes (16-byte header, 4-byte size per element)."""
    groups: list[list[int]] = []
    current: list[int] = []
    used = 16
    for i, n in enumerate(sizes):
        if 16 + 4 + n > max_datagram:
            raise ValueError(f"an OSC message of {n} bytes cannot fit a {max_datagram}-byte bundle")
        if current and used + 4 + n > max_datagram:
            groups.append(current)
            current, used = [], 16
        current.append(i)
        used += 4 + n
    if current:
        groups.append(current)
    return groups


def pack_datagrams(messages: Sequence[bytes], bundled: bool = True,
                   max_datagram: int = DEFAULT_MAX_DATAGRAM) -> list[bytes]:
    """Messages -> datagrams: bundles of at most ``max_datagram`` bytes, or one per message."""
    if not bundled:
        return list(messages)
    return [encode_bundle([messages[i] for i in g])
            for g in group_for_bundles([len(m) for m in messages], max_datagram)]


# ----------------------------------------------------------------------------- decoding

_ZEROS = {n: b"\x00" * n for n in range(1, 5)}  # the padding after a string's NUL, by length


def _padded_string(data: bytes, pos: int, end: int) -> tuple[bytes, int]:
    """The raw bytes of the NUL-terminated, 4-byte padded OSC string at ``pos``, and the
    position after its padding."""
    nul = data.find(b"\x00", pos, end)
    stop = (nul & ~3) + 4
    if nul < 0 or stop > end:
        raise _Bad("truncated")
    if data[nul:stop] != _ZEROS[stop - nul]:
        raise _Bad("bad_padding")
    return data[pos:nul], stop


def _read_string(data: bytes, pos: int, end: int) -> tuple[str, int]:
    raw, stop = _padded_string(data, pos, end)
    try:
        return raw.decode("utf-8"), stop
    except UnicodeDecodeError:
        raise _Bad("bad_string") from None


_plans: dict[bytes, tuple[str, tuple]] = {}  # raw type tags -> (tags, decoding steps)


def _compile(raw: bytes) -> tuple[str, tuple]:
    """Compile a type-tag string into steps: runs of fixed-size types become one Struct."""
    if raw[:1] != b",":
        raise _Bad("bad_type_tag")
    try:
        tags = raw[1:].decode("ascii")
    except UnicodeDecodeError:
        raise _Bad("bad_type_tag") from None
    steps: list = []
    run = ""
    for t in tags:
        if t in _FIXED:
            run += _FIXED[t]
            continue
        if run:
            steps.append(struct.Struct(">" + run))
            run = ""
        if t in ("s", "S", "b"):
            steps.append(t)
        elif t in _CONSTANT:
            steps.append(("const", _CONSTANT[t]))
        else:  # arrays and exotic types: VMC never sends them and we cannot size them
            raise _Bad("bad_type_tag")
    if run:
        steps.append(struct.Struct(">" + run))
    if len(_plans) >= _MAX_PLANS:
        _plans.clear()
    _plans[raw] = (tags, tuple(steps))
    return _plans[raw]


_addresses: dict[bytes, str] = {}  # raw address -> str: VMC repeats a handful of addresses


def _decode_message(data: bytes, pos: int, end: int) -> Message:
    # The address and type tags are looked up in caches keyed by their raw bytes: this is
    # the receive hot path (25 messages per performer per frame).
    raw, stop = _padded_string(data, pos, end)
    address = _addresses.get(raw)
    if address is None:
        if raw[:1] != b"/":
            raise _Bad("bad_address")
        try:
            address = raw.decode("utf-8")
        except UnicodeDecodeError:
            raise _Bad("bad_address") from None
        if len(_addresses) >= _MAX_PLANS:
            _addresses.clear()
        _addresses[raw] = address
    pos = stop
    if pos == end:  # OSC 1.0 allows omitting the type tag string: no arguments
        return address, "", ()
    raw, stop = _padded_string(data, pos, end)
    compiled = _plans.get(raw)
    if compiled is None:
        compiled = _compile(raw)
    tags, plan = compiled
    pos = stop
    if len(plan) == 1 and type(plan[0]) is struct.Struct:  # numbers only: one unpack
        step = plan[0]
        if pos + step.size != end:
            raise _Bad("truncated" if pos + step.size > end else "trailing_bytes")
        return address, tags, step.unpack_from(data, pos)
    args: list = []
    for step in plan:
        if type(step) is struct.Struct:
            if pos + step.size > end:
                raise _Bad("truncated")
            args.extend(step.unpack_from(data, pos))
            pos += step.size
        elif type(step) is tuple:
            args.append(step[1])
        elif step == "b":
            if pos + 4 > end:
                raise _Bad("truncated")
            (n,) = _INT.unpack_from(data, pos)
            stop = pos + 4 + n + (-n) % 4
            if n < 0 or stop > end:
                raise _Bad("truncated")
            if data.count(b"\x00", pos + 4 + n, stop) != stop - pos - 4 - n:
                raise _Bad("bad_padding")
            args.append(data[pos + 4:pos + 4 + n])
            pos = stop
        else:
            s, pos = _read_string(data, pos, end)
            args.append(s)
    if pos != end:
        raise _Bad("trailing_bytes")
    return address, tags, tuple(args)


def decode(datagram: bytes, on_error: Callable[[str], None]) -> tuple[bool, list[Message]]:
    """Decode one datagram into ``(is_bundle, messages)``; never raises on bad input.

    A bad message inside a well-framed bundle is reported and skipped, the rest kept. A
    framing error (bad element size, truncation) stops the bundle there. Bundles nested
    in bundles are reported (``nested_bundle``) and skipped: VMC never nests, and
    recursion is how a hostile packet exhausts the stack.
    """
    data = bytes(datagram)
    end = len(data)
    if end == 0:
        on_error("empty")
        return False, []
    if end % 4:
        on_error("bad_padding")
        return False, []
    first = data[:1]
    if first == b"/":
        try:
            return False, [_decode_message(data, 0, end)]
        except _Bad as bad:
            on_error(bad.reason)
            return False, []
    if first != b"#":
        on_error("not_osc")
        return False, []
    if not data.startswith(BUNDLE_TAG):
        on_error("bad_bundle_header")
        return True, []
    if end < 16:
        on_error("truncated")
        return True, []
    messages: list[Message] = []
    pos = 16  # tag (8) + time tag (8); the time tag is ignored: VMC plays everything now
    while pos < end:
        if pos + 4 > end:
            on_error("truncated")
            break
        (size,) = _INT.unpack_from(data, pos)
        pos += 4
        if size <= 0 or size % 4:
            on_error("bad_element_size")
            break
        if pos + size > end:
            on_error("oversized_element")
            break
        if data.startswith(b"#bundle", pos):
            on_error("nested_bundle")
        elif data[pos:pos + 1] == b"/":
            try:
                messages.append(_decode_message(data, pos, pos + size))
            except _Bad as bad:
                on_error(bad.reason)
        else:
            on_error("not_osc")
        pos += size
    return True, messages


def check_port(port: object, what: str) -> int:
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise UserError(f"{what} port {port!r} is not a UDP port; use a number from 1 to 65535 "
                        f"such as 39539")
    return port
