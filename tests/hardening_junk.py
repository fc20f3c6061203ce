"""Hostile datagrams for the hardening tests and bench/flood.py, made fast.

A seeded mutation generator over byte-literal seeds (valid VMC frames, valid control
commands): numpy draws every choice for a whole batch at once and each datagram is then
one or two slicing/concatenation operations, so 200,000 datagrams cost about a second of
CPU instead of the ~3 ms per example hypothesis spends drawing.

Every datagram carries the *class* of mutation that made it. Some classes are rejected
by construction and name the reason the receiver must count (``MUST``); the others
(truncation, byte flips, random bytes) may by chance still be valid OSC, which the tests
then check with an independent parser.
"""

from __future__ import annotations

import struct
from collections import Counter

import numpy as np

from stylecast.drivers.vmc.osc_packets import encode_bundle, encode_message, osc_string
from stylecast.drivers.vmc.vmc_out import encode_frame
from stylecast.motion import rotations as rot
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default

J = len(HUMANOID_BONES)

CLASSES = ("truncate", "flip", "type_tags", "padding", "nested", "oversized", "nan_inf", "huge_string",
           "unknown_address", "random", "element_size", "zero_quaternion")

# For VMC input: classes that are rejected whatever the random draw, and the counter
# reason each must raise at least once.
VMC_MUST = {
    "nested": {"nested_bundle"},
    "nan_inf": {"non_finite"},
    "unknown_address": {"unknown_address", "ignored_vmc"},  # /VMC/... addresses we do not read
    "element_size": {"bad_element_size", "oversized_element"},
    "zero_quaternion": {"bad_quaternion"},
    "padding": {"bad_padding"},
    "huge_string": {"unknown_address", "truncated", "ignored_bone"},
}
CONTROL_MUST = {
    "nested": {"malformed_nested_bundle"},
    "nan_inf": {"bad_arguments"},
    "unknown_address": {"unknown_address"},
    "element_size": {"malformed_bad_element_size", "malformed_oversized_element"},
    "padding": {"malformed_bad_padding"},
    "huge_string": {"unknown_address", "bad_arguments", "malformed_truncated", "malformed_oversized_element"},
}

_NAN = struct.pack(">f", float("nan"))
_NON_FINITE = (_NAN, struct.pack(">f", float("inf")), struct.pack(">f", float("-inf")), b"\xff\xc0\x00\x01")
_TAGS = [osc_string(t) for t in (",iiiiiiii", ",sfff", ",fffffffs", ",s", ",f", ",i", ",Z", ",[f]", ",b", ",h",
                                 ",d", ",ssssssss", ",T", ",", "sfffffff", ",sfffffffffffffffffffffffff")]
_ADDRESSES = [osc_string(a) for a in ("/VMC/Ext/Unknown", "/foo", "/avatar/parameters/X", "/VMC", "/stylecast",
                                      "/stylecast/xyz", "/VMC/Ext/Bone/Pos/Extra", "/tracking/trackers/1/position")]


def bone_message(name: str, values) -> bytes:
    return osc_string("/VMC/Ext/Bone/Pos") + osc_string(",sfffffff") + osc_string(name) + struct.pack(">7f", *values)


def vmc_seeds() -> list[bytes]:
    """Valid VMC datagrams: bundled frames, every message of an unbundled one, trackers."""
    rng = np.random.default_rng(7)
    offsets = humanoid_skeleton_default().offsets
    seeds = []
    for k in range(3):
        q = rot.from_euler(rng.normal(0, 30, (J, 3)), "ZXY")
        root = np.array([rng.normal(0, 50), 90.0, rng.normal(0, 50)])
        seeds += encode_frame(root, q, offsets, k / 60.0)
        seeds += encode_frame(root, q, offsets, k / 60.0, bundled=False)
    seeds.append(encode_message("/VMC/Ext/Tra/Pos", "tracker-1", 0.1, 1.0, 0.2, 0.0, 0.0, 0.0, 1.0))
    seeds.append(encode_message("/VMC/Ext/Blend/Val", "A", 0.5))
    return seeds


def control_seeds(performers=("p0", "p1")) -> list[bytes]:
    seeds = [encode_message("/stylecast/intensity", 0.5), encode_message("/stylecast/bypass", 1),
             encode_message("/stylecast/bypass", 0), encode_message("/stylecast/crossfade", 0.25),
             encode_message("/stylecast/direction", "b2a"), encode_message("/stylecast/model", "identity"),
             encode_message("/stylecast/status")]
    for p in performers:
        seeds += [encode_message("/stylecast/intensity", 0.8, p), encode_message("/stylecast/bypass", 0, p)]
    seeds.append(encode_bundle(seeds[:3]))
    return seeds


def _split_message(m: bytes) -> tuple[bytes, bytes, bytes]:
    """(address, type tags, arguments) of an encoded message, all padded."""
    a = (m.index(b"\x00") & ~3) + 4
    if a >= len(m) or m[a:a + 1] != b",":
        return m[:a], b"", m[a:]
    t = (m.index(b"\x00", a) & ~3) + 4
    return m[:a], m[a:t], m[t:]


class JunkGenerator:
    """``batch(n)`` -> (datagrams, class indices); deterministic for a seed."""

    def __init__(self, seeds: list[bytes], seed: int = 0, kind: str = "vmc", max_size: int = 65000):
        self.seeds = seeds
        self.messages = [s for s in seeds if s[:1] == b"/"] or [encode_message("/x", 1.0)]
        self.rng = np.random.default_rng(seed)
        self.kind = kind
        self.max_size = max_size
        self._pose = [m for m in self.messages if m.startswith(osc_string("/VMC/Ext/Bone/Pos"))]
        if kind == "control":
            self._numeric = [encode_message(a, 0.5) for a in ("/stylecast/intensity", "/stylecast/crossfade")]
        else:
            self._numeric = self._pose

    def batch(self, n: int) -> tuple[list[bytes], np.ndarray]:
        rng = self.rng
        classes = rng.integers(0, len(CLASSES), n)
        if self.kind == "control":  # a zero quaternion means nothing to the control port
            classes[classes == CLASSES.index("zero_quaternion")] = CLASSES.index("nan_inf")
        which = rng.integers(0, 1 << 30, n)
        a = rng.integers(0, 1 << 30, n)
        b = rng.integers(0, 256, (n, 4))
        out = []
        for k in range(n):
            out.append(self._make(int(classes[k]), int(which[k]), int(a[k]), b[k]))
        return out, classes

    # Each branch is one cheap byte operation on a seed.
    def _make(self, c: int, which: int, a: int, b: np.ndarray) -> bytes:
        seeds, messages = self.seeds, self.messages
        seed = seeds[which % len(seeds)]
        name = CLASSES[c]
        if name == "truncate":
            return seed[:a % len(seed)]
        if name == "flip":
            d = bytearray(seed)
            for i in range(1 + a % 4):
                d[(a >> (4 + 7 * i)) % len(d)] = int(b[i])
            return bytes(d)
        if name == "type_tags":
            addr, _, args = _split_message(messages[which % len(messages)])
            return addr + _TAGS[a % len(_TAGS)] + args
        if name == "padding":
            m = messages[which % len(messages)]
            if a % 2:  # a non-zero byte where the address' NUL padding must be
                d = bytearray(m)
                nul = d.index(b"\x00")
                pad_end = (nul & ~3) + 4
                if pad_end - nul > 1:
                    d[pad_end - 1] = 1 + int(b[0]) % 255
                    return bytes(d)
            return m + bytes(1 + a % 3)  # a length that is not a multiple of 4
        if name == "nested":
            inner = messages[which % len(messages)]
            for _ in range(1 + a % 40):
                inner = encode_bundle([inner])
                if len(inner) > 4000:
                    break
            return encode_bundle([inner])
        if name == "oversized":
            m = messages[which % len(messages)]
            if a % 3 == 0:  # a valid bundle beyond any MTU (rarely up to 64 KB), of messages nobody reads
                unknown = _ADDRESSES[a % len(_ADDRESSES)] + osc_string(",f") + b"\x00" * 4
                count = 2000 if (a >> 12) % 100 == 0 else 20 + a % 40
                return encode_bundle([unknown] * min(self.max_size // (len(unknown) + 4) - 1, count))
            if a % 3 == 1:  # an element claiming 2 GiB
                return b"#bundle\x00" + bytes(7) + b"\x01" + struct.pack(">i", 0x7FFFFFFC) + m
            return encode_bundle([m] * (1 + a % 10))  # many copies of a valid message
        if name == "nan_inf":
            m = self._numeric[which % len(self._numeric)]
            bad = _NON_FINITE[a % len(_NON_FINITE)]
            slot = len(m) - 4 * (1 + a % 7) if self.kind == "vmc" else len(m) - 4
            return m[:slot] + bad + m[slot + 4:]
        if name == "huge_string":
            # mostly 1-8 KB; one in 20 up to the largest UDP payload (each costs its size to make and parse)
            size = 1000 + (a >> 8) % (self.max_size - 2000 if a % 20 == 0 else 7000)
            if a % 3 == 0:  # a huge address
                return osc_string("/" + "A" * size) + osc_string(",f") + b"\x00" * 4
            if a % 3 == 1:  # a huge string argument
                addr = osc_string("/stylecast/model" if self.kind == "control" else "/VMC/Ext/Bone/Pos")
                if self.kind == "control":
                    return addr + osc_string(",s") + osc_string("m" * size)
                return addr + osc_string(",sfffffff") + osc_string("N" * size) + struct.pack(">7f", 0, 0, 0, 0, 0, 0, 1)
            return b"/" + b"B" * (size - size % 4 + 3)  # an address that never ends
        if name == "unknown_address":
            _, tags, args = _split_message(messages[which % len(messages)])
            return _ADDRESSES[a % len(_ADDRESSES)] + (tags or osc_string(",")) + args
        if name == "random":
            size = a % 1500
            head = (b"", b"/", b"#bundle\x00")[a % 3]
            return head + self.rng.bytes(size)
        if name == "element_size":
            m = messages[which % len(messages)]
            size = (-4, 0, 6, 3, len(m) + 4, len(m) + 400, -(1 << 31))[a % 7]
            return b"#bundle\x00" + bytes(7) + b"\x01" + struct.pack(">i", size) + m
        if name == "zero_quaternion":
            bone = HUMANOID_BONES[a % J]
            return bone_message(bone, (0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0))
        raise AssertionError(name)


def udp_payload_ok(d: bytes) -> bool:
    return len(d) <= 65507


# ------------------------------------------------------------------- flood helpers
# Process targets for bench/flood.py and tests/test_hardening_flood.py (forked, so they
# must only need what they are given).

_VMC_CONTENT = ("wrong_type", "missing_args", "non_finite", "bad_quaternion", "unknown_address", "ignored_vmc",
                "ignored_bone", "too_many_performers")


def single_reason_junk(kind: str, n: int, seed: int = 0) -> tuple[list[bytes], Counter]:
    """``n`` junk datagrams that the VMC parser (kind "vmc") or the control port (kind
    "control") rejects with exactly one counted reason and no message used, so that
    live "reasons counted == datagrams read" is an exact check; and the expected reasons."""
    from collections import Counter

    from stylecast.daemon.control import ControlServer
    from stylecast.drivers.vmc.vmc_parse import VmcParser

    gen = JunkGenerator(vmc_seeds() if kind == "vmc" else control_seeds(("p0",)), seed=seed, kind=kind)
    out: list[bytes] = []
    expected: Counter = Counter()
    if kind == "vmc":
        parser = VmcParser("junk")
        counts, skip = parser.counters, ("datagrams", "messages", "frames", "expired_frames")
        feed = lambda d: parser.feed(d, ("127.0.0.1", 1), 0.0)  # noqa: E731
    else:
        server = ControlServer("127.0.0.1", 0)
        server.close()
        counts, skip = server.counts, ("datagrams",)
        feed = lambda d: (server.handle(d, ("127.0.0.1", 1)), server.drain())  # noqa: E731
    while len(out) < n:
        batch, _ = gen.batch(4 * n)
        for d in batch:
            if len(d) > 1400:  # keep the flood in packets, not bytes
                continue
            before = dict(counts)
            feed(d)
            delta = {k: v - before.get(k, 0) for k, v in counts.items() if k not in skip and v != before.get(k, 0)}
            content = sum(v for k, v in delta.items() if k in _VMC_CONTENT)
            used = counts.get("messages", 0) - before.get("messages", 0) - content if kind == "vmc" \
                else delta.get("accepted", 0)
            if len(delta) == 1 and sum(delta.values()) == 1 and "accepted" not in delta and used == 0:
                out.append(d)
                expected.update(delta)
                if len(out) == n:
                    break
    return out, expected


def junk_sender(streams, rate, duration, go, results) -> None:
    """``streams``: [(target, datagrams)]. Once ``go`` is set, send at ``rate`` datagrams
    per second for ``duration`` seconds, targets in turn, each cycling through its own
    datagrams; put ("junk", {"host:port": count sent}, seconds taken) on ``results``."""
    import socket
    import time

    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 22)
    targets = [t for t, _ in streams]
    lists = [d for _, d in streams]
    cursor = [0] * len(streams)
    sent = [0] * len(streams)
    go.wait()
    t0 = time.monotonic()
    n, total = 0, int(duration * rate)
    while n < total:
        now = time.monotonic() - t0
        if now >= duration + 1.0:  # the box could not keep the rate: stop anyway
            break
        due = min(int(now * rate) + 1, total)
        while n < due:
            t = n % len(streams)
            try:
                sock.sendto(lists[t][cursor[t]], targets[t])
                sent[t] += 1
            except OSError:
                pass  # a refused send never reached the daemon: it is simply not counted as sent
            cursor[t] = (cursor[t] + 1) % len(lists[t])
            n += 1
        time.sleep(0.0005)
    elapsed = time.monotonic() - t0
    sock.close()
    results.put(("junk", {f"{h}:{p}": c for (h, p), c in zip(targets, sent)}, elapsed))


def vmc_performers_sender(targets, clip_rotations, clip_roots, offsets, duration, go, results) -> None:
    """One VMC sender per target, each replaying the clip at 60 fps; /VMC/Ext/T carries the
    frame index (so the receiving side can tell exactly which frames arrived)."""
    import time

    from stylecast.drivers.vmc.vmc_out import VmcSender

    senders = [VmcSender([t]) for t in targets]
    go.wait()
    t0 = time.monotonic()
    i, T = 0, len(clip_rotations)
    while i / 60.0 < duration:
        wait = t0 + i / 60.0 - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        for s in senders:
            s.send_frame(clip_roots[i % T], clip_rotations[i % T], offsets, float(i))
        i += 1
    results.put(("legit", {f"{h}:{p}": s.frames_sent for (h, p), s in zip(targets, senders)},
                 {f"{h}:{p}": dict(s.errors[0]) for (h, p), s in zip(targets, senders)}))
    for s in senders:
        s.close()


def vmc_frame_receiver(socks, duration, ready, results) -> None:
    """Receive VMC on each (already bound, inherited) socket for ``duration`` seconds; put
    ("received", {port: [/VMC/Ext/T of every frame]}) on ``results``."""
    import select
    import time

    from stylecast.drivers.vmc.vmc_parse import VmcParser

    ports = [s.getsockname()[1] for s in socks]
    parsers = [VmcParser(f"out{p}") for p in ports]
    times = {p: [] for p in ports}
    for s in socks:
        s.setblocking(False)
    ready.set()
    end = time.monotonic() + duration
    while time.monotonic() < end:
        readable, _, _ = select.select(socks, [], [], 0.05)
        for s in readable:
            i = socks.index(s)
            while True:
                try:
                    d, addr = s.recvfrom(65536)
                except BlockingIOError:
                    break
                for f in parsers[i].feed(d, addr, 0.0):
                    times[ports[i]].append(f.sender_time)
    for s in socks:
        s.close()
    results.put(("received", times))


def bind_consecutive(n: int, rcvbuf: int = 1 << 22) -> list:
    """``n`` UDP sockets bound to consecutive loopback ports (performer k -> base + k)."""
    import socket

    for _ in range(100):
        first = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        first.bind(("127.0.0.1", 0))
        socks = [first]
        try:
            for k in range(1, n):
                s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                socks.append(s)
                s.bind(("127.0.0.1", first.getsockname()[1] + k))
        except OSError:
            for s in socks:
                s.close()
            continue
        for s in socks:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        return socks
    raise RuntimeError(f"no {n} consecutive free UDP ports on 127.0.0.1")


def peak_rss_mb() -> tuple[float, float]:
    """(VmRSS, VmHWM) of this process in MB."""
    rss = hwm = 0.0
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                rss = int(line.split()[1]) / 1024
            elif line.startswith("VmHWM:"):
                hwm = int(line.split()[1]) / 1024
    return rss, hwm


def udp_rcvbuf_errors() -> int:
    """Datagrams the kernel dropped for full receive buffers (this network namespace)."""
    try:
        with open("/proc/net/snmp") as f:
            lines = [line.split() for line in f if line.startswith("Udp:")]
        return int(lines[1][lines[0].index("RcvbufErrors")])
    except (OSError, ValueError, IndexError):
        return -1
