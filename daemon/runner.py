"""Running the daemon as a process: real clock, signals, clean shutdown.

Ctrl-C and SIGTERM only set a stop event; the output loop finishes its tick and
``Daemon.close`` stops the threads and closes the recordings (frame count written), so
a stopped daemon always leaves a valid BVH file behind.
"""

from __future__ import annotations

import logging
import signal
import threading

from stylecast.drivers.sources import open_source
from stylecast.motion.clock import RealClock

from .config import DaemonConfig
from .engine import Daemon
from .restylers import load_restyler

log = logging.getLogger("stylecast.daemon")


def open_sources(urls: list[str], first_index: int = 0) -> list:
    """Sources for ``urls``; unnamed ones are p{k}, k counted from ``first_index`` (a
    worker process serving performers first_index.. of the whole daemon)."""
    sources = []
    try:
        for k, url in enumerate(urls, start=first_index):
            sources.append(open_source(url, f"p{k}"))
    except BaseException:
        for s in sources:
            s.close()
        raise
    return sources


def install_stop_handlers(stop: threading.Event) -> None:
    def handler(signum, frame):
        stop.set()

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, handler)
        signal.signal(signal.SIGTERM, handler)


def run_daemon(config: DaemonConfig, restyler=None, sources=None, stop: threading.Event | None = None,
               on_started=None) -> int:
    stop = stop or threading.Event()
    install_stop_handlers(stop)
    if sources is None:
        sources = open_sources(config.source)  # cheap errors (bad URL, missing file) first
    if restyler is None:
        try:
            restyler = load_restyler(config.model, config.device)
        except BaseException:
            for s in sources:
                s.close()
            raise
    daemon = Daemon(config, sources, restyler, RealClock(stop))
    try:
        log.info("serving %d performer(s), hop %d, delay %d frames, model %s; control %s",
                 len(daemon.sessions), daemon.settings.hop, daemon.settings.delay, daemon.style,
                 "%s:%d" % daemon.control.address if daemon.control else "off")
        if on_started is not None:
            on_started(daemon)
        daemon.run(stop, config.duration)
    finally:
        daemon.close()
        for line in daemon.status_lines():
            log.info("final: %s", line)
        if config.record:
            log.info("recording closed: %s", config.record)
    return 0
