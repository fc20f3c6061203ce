"""``serve --workers N``: the performers spread over N worker processes.

The GIL holds one process to one core. Each worker process runs a whole ``Daemon`` over
a contiguous slice of the sources, with its own model, its own batched model calls,
its own output clock and the sockets its performers own; they share nothing else.
Performer k keeps its global name (p{k}), output port (PORT + k) and recording
(out.k.bvh) whichever worker serves it.

The parent owns the control port: a command naming a performer goes to the worker that
serves it (an unknown name is refused in one sentence, as by a single daemon), other
commands go to every worker, and ``/stylecast/status`` gathers every worker's snapshot
into one reply, so control and status see all performers.

Messages over each worker's pipe: parent -> worker ("apply", command, value, performer),
("status",), ("stop",); worker -> parent ("ready", [names]) or ("error", sentence) once,
("status", snapshot) per request, ("final", [status lines]) at the end.
"""

from __future__ import annotations

import dataclasses
import logging
import multiprocessing as mp
import threading
import time

from stylecast.motion.errors import UserError

from .config import DaemonConfig

log = logging.getLogger("stylecast.daemon")
START_TIMEOUT_S = 300.0  # loading a model on a busy machine can take a while
STATUS_TIMEOUT_S = 0.5  # a worker answers within a tick or two
POLL_S = 0.01


def split(count: int, workers: int) -> list[range]:
    """Contiguous, balanced slices of ``count`` performers over at most ``workers``."""
    workers = max(1, min(workers, count))
    bounds = [round(i * count / workers) for i in range(workers + 1)]
    return [range(a, b) for a, b in zip(bounds, bounds[1:]) if b > a]


def worker_main(config: DaemonConfig, first: int, worker: tuple[int, int], conn) -> None:
    """One worker process: a Daemon over config.source, performers numbered from ``first``;
    ``worker``: its index and the number of worker processes."""
    from stylecast.motion.clock import RealClock
    from .engine import Daemon
    from .restylers import load_restyler
    from .runner import install_stop_handlers, open_sources

    logging.basicConfig(level=logging.INFO, format=f"%(asctime)s [worker {first}] %(message)s", datefmt="%H:%M:%S")
    stop = threading.Event()
    install_stop_handlers(stop)
    daemon = None
    try:
        sources = open_sources(config.source, first)
        try:
            restyler = load_restyler(config.model, config.device)
            daemon = Daemon(config, sources, restyler, RealClock(stop), first_index=first, remote=conn,
                            worker=worker)
        except BaseException:
            for s in sources:
                s.close()
            raise
    except UserError as exc:
        conn.send(("error", str(exc)))
        return
    conn.send(("ready", [s.performer for s in daemon.sessions]))
    try:
        daemon.run(stop, config.duration)
    finally:
        daemon.close()
        try:
            conn.send(("final", daemon.status_lines()))
        except (OSError, BrokenPipeError):
            pass


class _Worker:
    def __init__(self, ctx, config: DaemonConfig, first: int, worker: tuple[int, int]):
        self.first = first
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=worker_main, args=(config, first, worker, child), name=f"stylecast-worker-{first}",
                                   daemon=True)
        self.process.start()
        child.close()
        self.names: list[str] = []
        self.final: list[str] = []

    def expect(self, kind: str, timeout: float):
        """The next message of ``kind`` (other kinds are handled on the way), or None."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            try:
                if left <= 0 or not self.conn.poll(left):
                    return None
                message = self.conn.recv()
            except (EOFError, OSError):
                return None
            if message[0] == kind or message[0] == "error":
                return message
            if message[0] == "final":
                self.final = message[1]

    def send(self, *message) -> None:
        try:
            self.conn.send(message)
        except (OSError, BrokenPipeError):
            pass  # a worker that ended has nothing left to change


def merge_snapshots(snapshots: list[dict], control_refused: int) -> dict:
    daemons = [s["daemon"] for s in snapshots]
    first = daemons[0]
    return {"daemon": {**first, "performers": sum(d["performers"] for d in daemons),
                       "ticks": max(d["ticks"] for d in daemons),
                       "dropped_ticks": sum(d["dropped_ticks"] for d in daemons),
                       "faults": sum(d["faults"] for d in daemons), "control_refused": control_refused,
                       "workers": len(daemons)},
            "performers": [p for s in snapshots for p in s["performers"]]}


def run_workers(config: DaemonConfig, stop: threading.Event | None = None, on_started=None) -> int:
    from .control import ControlServer
    from .status import status_messages
    from .runner import install_stop_handlers

    stop = stop or threading.Event()
    install_stop_handlers(stop)
    ctx = mp.get_context("spawn")  # no forked torch or socket state in the children
    workers = []
    control = None
    try:
        parts = split(len(config.source), config.processes)
        for index, part in enumerate(parts):
            sub = dataclasses.replace(config, source=config.source[part.start:part.stop], control="off")
            workers.append(_Worker(ctx, sub, part.start, (index, len(parts))))
        for w in workers:
            message = w.expect("ready", START_TIMEOUT_S)
            if message is None:
                raise UserError(f"worker process for performers from p{w.first} did not start within "
                                f"{START_TIMEOUT_S:.0f} s; check the log above, or run with --workers 1")
            if message[0] == "error":
                raise UserError(message[1])
            w.names = message[1]
        owner = {name: w for w in workers for name in w.names}
        address = config.control_address()
        if address is not None:
            control = ControlServer(*address, allow=config.allow)
        log.info("serving %d performer(s) in %d worker processes; control %s", len(owner), len(workers),
                 "%s:%d" % control.address if control else "off")
        if on_started is not None:
            on_started(control)
        while not stop.is_set() and any(w.process.is_alive() for w in workers):
            if control is not None:
                _serve_control(control, workers, owner, status_messages)
            time.sleep(POLL_S)
    finally:
        for w in workers:
            w.send("stop")
        for w in workers:
            if not w.final:
                message = w.expect("final", 10.0)
                if message is not None and message[0] == "final":
                    w.final = message[1]
            w.process.join(10.0)
            if w.process.is_alive():
                w.process.terminate()
        if control is not None:
            control.close()
        for w in workers:
            for line in w.final:
                log.info("final: %s", line)
    return 0


def _serve_control(control, workers, owner, status_messages) -> None:
    for command, value, performer, addr in control.drain():
        if command == "status":
            snapshots = []
            for w in workers:
                w.send("status")
            for w in workers:
                message = w.expect("status", STATUS_TIMEOUT_S)
                if message is not None and message[0] == "status":
                    snapshots.append(message[1])
            if snapshots:
                control.reply(addr, status_messages(merge_snapshots(snapshots, control.refused)))
        elif performer is not None:
            if performer in owner:
                owner[performer].send("apply", command, value, performer)
            else:
                log.warning("control: no performer called %r", performer)
        else:
            for w in workers:
                w.send("apply", command, value, None)
