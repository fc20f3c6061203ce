"""The one description of the machine every benchmark prints beside its table: these
machines are shared and noisy, so the CPU model, core count and load come with each run."""

from __future__ import annotations

import os
import platform


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            return next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        return platform.processor() or platform.machine()


def describe(*extra: str) -> str:
    """e.g. "AMD EPYC ..., 2 logical CPUs, load average 0.52, Linux 6.1, Python 3.11.7, numpy 2.4.6"."""
    import numpy

    load = f"load average {os.getloadavg()[0]:.2f}" if hasattr(os, "getloadavg") else "load average ?"
    parts = [cpu_model(), f"{os.cpu_count()} logical CPUs", load, f"{platform.system()} {platform.release()}",
             f"Python {platform.python_version()}", f"numpy {numpy.__version__}", *extra]
    return ", ".join(parts)
