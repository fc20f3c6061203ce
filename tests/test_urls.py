"""One URL grammar for every source and sink: each scheme's own options, duplicates and
unknown options refused in one sentence, wherever the URL is used."""

from __future__ import annotations

import pytest

from stylecast.drivers.serial.serial_trackers import parse_serial_url
from stylecast.drivers.sinks import SINK_SCHEMES, open_sink
from stylecast.drivers.sources import SOURCE_SCHEMES, open_source
from stylecast.drivers.urls import parse_url, parse_vmc_url
from stylecast.drivers.vmc.vmc_in import VmcReceiver
from stylecast.drivers.vmc.vmc_out import VmcSender
from stylecast.motion.errors import UserError


def _source(url):
    open_source(url, "p0").close()


def _sink(url):
    parsed = parse_url(url)
    open_sink(parsed, [(parsed.host or "127.0.0.1", parsed.port or 9000)]).close()


OPENERS = {
    "bvh source": (_source, "bvh:///x.bvh?loop=1"),
    "vmc source": (_source, "vmc://127.0.0.1:0?name=a"),
    "serial source": (_source, "serial:///dev/null?baud=9600"),
    "vmc sink": (_sink, "vmc://127.0.0.1:39539?bundled=1"),
    "vrchat sink": (_sink, "vrchat://127.0.0.1:9000?head=1"),
    "VmcSender.from_urls": (lambda u: VmcSender.from_urls([u]).close(), "vmc://127.0.0.1:39539?bundled=1"),
    "VmcReceiver.from_url": (lambda u: VmcReceiver.from_url(u).close(), "vmc://127.0.0.1:0?performer=a"),
    "parse_serial_url": (parse_serial_url, "serial:///dev/ttyUSB0?baud=9600"),
}


def _one_sentence(exc: UserError) -> str:
    message = str(exc)
    assert "\n" not in message and "Traceback" not in message
    return message


@pytest.mark.parametrize("where", sorted(OPENERS))
def test_duplicate_and_unknown_options_are_refused_everywhere(where):
    opener, url = OPENERS[where]
    key, value = url.split("?")[1].split("=")
    with pytest.raises(UserError) as twice:
        opener(f"{url}&{key}={value}")
    assert f"option {key} is given twice" in _one_sentence(twice.value)
    with pytest.raises(UserError) as unknown:
        opener(f"{url}&lop=1")
    assert "unknown option lop" in _one_sentence(unknown.value)


def test_every_scheme_is_registered_once_with_its_factory():
    assert set(SOURCE_SCHEMES) == {"bvh", "vmc", "serial"}
    assert set(SINK_SCHEMES) == {"vmc", "vrchat"}
    with pytest.raises(UserError, match="unknown source scheme 'osc'"):
        open_source("osc://127.0.0.1:1", "p0")
    with pytest.raises(UserError, match="unknown output scheme 'osc'"):
        _sink("osc://127.0.0.1:1")


def test_the_grammar_keeps_what_was_written():
    u = parse_url("serial://COM3?baud=115200")
    assert (u.scheme, u.netloc, u.options) == ("serial", "COM3", {"baud": "115200"})
    assert parse_serial_url("serial://COM3?baud=115200") == ("COM3", {"baudrate": 115200})
    assert parse_vmc_url("vmc://localhost:39540?bundled=0", ("bundled",)) == ("localhost", 39540, {"bundled": "0"})
    assert parse_url("/clips/a.bvh.gz").scheme == "bvh"
