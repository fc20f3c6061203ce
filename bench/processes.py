"""Run one function in several spawned processes at once, as ``serve --workers`` runs its
daemons: each starts its clock only when all are ready, and each sends back its figures."""

from __future__ import annotations

import multiprocessing as mp


def run_together(target, args_per_process: list[tuple]) -> list:
    """``target(*args, start, conn)`` in one spawned process per ``args``: it waits on
    ``start`` (a barrier passed once every process is ready) and sends its result over
    ``conn``. Returns the results in the order of ``args_per_process``."""
    ctx = mp.get_context("spawn")
    start = ctx.Barrier(len(args_per_process))
    procs, pipes = [], []
    for args in args_per_process:
        parent, child = ctx.Pipe(duplex=False)
        proc = ctx.Process(target=target, args=(*args, start, child))
        proc.start()
        procs.append(proc)
        pipes.append(parent)
    results = [pipe.recv() for pipe in pipes]
    for proc in procs:
        proc.join()
    return results
