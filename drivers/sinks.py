"""Sinks by URL scheme: the registry ``--out`` and ``--out-input`` URLs go through.

Like sources (``sources.py``), each scheme names ``module:function`` and is imported only
when a URL with that scheme is used. A factory has the signature
``factory(url: EndpointUrl, targets: [(host, port)], bundled: bool, tap) -> sink`` and
refuses options it does not know (``EndpointUrl.take``). A sink has
``send(root_position, rotations, offsets, time)``, ``counters()`` and ``close()``:
root position in cm and local rotations of the canonical humanoid (internal space),
``offsets`` the performer's bone offsets in cm.
"""

from __future__ import annotations

import importlib

from stylecast.motion.errors import UserError

from stylecast.drivers.urls import EndpointUrl

# scheme -> (module, factory, default port or None when the port must be given)
SINK_SCHEMES: dict[str, tuple[str, str, int | None]] = {
    "vmc": ("stylecast.drivers.vmc.vmc_out", "open_sink", None),
    "vrchat": ("stylecast.drivers.vrchat.vrchat_out", "open_sink", 9000),
}


def sink_schemes() -> list[str]:
    return sorted(SINK_SCHEMES)


def check_sink_scheme(url: EndpointUrl) -> None:
    if url.scheme not in SINK_SCHEMES:
        raise UserError(f"{url.text}: unknown output scheme {url.scheme!r}; outputs are "
                        f"{', '.join(s + '://HOST:PORT' for s in sink_schemes())}")


def default_port(url: EndpointUrl) -> int:
    check_sink_scheme(url)
    port = SINK_SCHEMES[url.scheme][2]
    if port is None:
        raise UserError(f"{url.text}: give the receiver's port, as in {url.scheme}://127.0.0.1:39539")
    return port


def open_sink(url: EndpointUrl, targets: list[tuple[str, int]], bundled: bool = True, tap=None):
    check_sink_scheme(url)
    module_name, function, _ = SINK_SCHEMES[url.scheme]
    factory = getattr(importlib.import_module(module_name), function)
    return factory(url, targets, bundled=bundled, tap=tap)
