"""The one description of the machine every benchmark prints beside its table: these
machines are shared and noisy, so the CPU model, core count and load come with each run."""

from __future__ import annotations

import os
import platform
import subprocess
from pathlib import Path


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            return next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        return platform.processor() or platform.machine()


def code_measured() -> str:
    """Where the stylecast being measured was imported from, and its commit: a bench run
    from a git worktree imports the installed checkout unless PYTHONPATH names the
    worktree, and an A/B against "the code before" then measures one code twice (it
    happened: docs/MEASUREMENTS.md, the multistyle capacity row)."""
    try:
        import stylecast.models
    except ImportError:
        return "code: stylecast not importable"
    where = Path(stylecast.models.__file__).resolve().parents[1]
    def git(*args: str) -> str:
        try:
            return subprocess.run(["git", "-C", str(where), *args], capture_output=True, text=True,
                                  timeout=5).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""

    commit = git("rev-parse", "--short", "HEAD")
    # A run before committing measures the working tree, not the commit: say so.
    changed = commit and git("status", "--porcelain", "--untracked-files=no")
    return f"code {where}" + (f" at {commit}" if commit else "") + (" with uncommitted changes" if changed else "")


def describe(*extra: str) -> str:
    """e.g. "AMD EPYC ..., 2 logical CPUs, load average 0.52, Linux 6.1, Python 3.11.7, numpy 2.4.6,
    code /work/main at 1523f30"."""
    import numpy

    load = f"load average {os.getloadavg()[0]:.2f}" if hasattr(os, "getloadavg") else "load average ?"
    parts = [cpu_model(), f"{os.cpu_count()} logical CPUs", load, f"{platform.system()} {platform.release()}",
             f"Python {platform.python_version()}", f"numpy {numpy.__version__}", *extra, code_measured()]
    return ", ".join(parts)
