"""Imports flow one way (ARCHITECTURE.md): motion <- drivers, models <- daemon; inside
drivers, the base (urls, sources, sinks) <- trackers <- serial, vmc <- vrchat, and bvh
beside them. Checked on the source text, so a wrong import fails here, not in a cycle."""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
# sub-package -> the drivers sub-packages it may import ("" is the base: urls, sources, sinks)
DRIVERS_MAY_IMPORT = {
    "": {""},
    "trackers": {"", "trackers"},
    "serial": {"", "serial", "trackers"},
    "vmc": {"", "vmc", "trackers"},
    "vrchat": {"", "vrchat", "vmc"},
    "bvh": {"", "bvh"},
}
BASE_MODULES = {"urls", "sources", "sinks", "cli"}


def imported_modules(path: Path) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return out


def drivers_part(module: str) -> str | None:
    parts = module.split(".")
    if parts[:2] != ["stylecast", "drivers"] or len(parts) < 3:
        return None
    return "" if parts[2] in BASE_MODULES else parts[2]


def test_drivers_sub_packages_import_one_way():
    bad = []
    for path in sorted((REPO / "drivers").rglob("*.py")):
        rel = path.relative_to(REPO / "drivers")
        if rel.name == "cli.py" and len(rel.parts) == 1:
            continue  # the `emulate` command sits on top of every driver
        own = rel.parts[0] if len(rel.parts) > 1 else ""
        for module in imported_modules(path):
            part = drivers_part(module)
            if part is not None and part not in DRIVERS_MAY_IMPORT[own]:
                bad.append(f"drivers/{rel} imports {module}")
            if module.startswith(("stylecast.daemon", "stylecast.models", "stylecast.viewer")):
                bad.append(f"drivers/{rel} imports {module}")
    assert not bad, bad


def test_motion_imports_nothing_above_it():
    bad = [f"{p.relative_to(REPO)} imports {m}" for p in (REPO / "motion").rglob("*.py") for m in imported_modules(p)
           if m.startswith("stylecast.") and not m.startswith("stylecast.motion")]
    assert not bad, bad


def test_no_driver_module_is_left_at_its_old_path():
    old = ("osc_packets", "vmc_in", "vmc_out", "serial_trackers", "trackers", "solver", "emulator",
           "bvh_replay", "bvh_recorder", "vrchat_out")
    assert not [n for n in old if (REPO / "drivers" / f"{n}.py").exists()]
