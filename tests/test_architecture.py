"""The host's layering holds (docs/architecture.md): every import of every module, including the
ones inside functions, points in the allowed direction."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "pmsm_hil"

# package -> packages of pmsm_hil it must never import (directly or inside a function)
FORBIDDEN = {
    "errors": {"*"},
    "names": {"*"},
    "files": {"*"},
    "profiles": {
        "protocol",
        "transport",
        "emulator",
        "runner",
        "recorder",
        "device",
        "cli",
        "log",
        "analysis",
        "gap",
        "live",
        "bench",
        "sweep",
    },
    "log": {
        "protocol",
        "transport",
        "emulator",
        "runner",
        "recorder",
        "device",
        "cli",
        "profiles",
        "analysis",
        "gap",
        "live",
        "bench",
        "sweep",
    },
    "protocol": {
        "transport",
        "emulator",
        "runner",
        "recorder",
        "device",
        "cli",
        "log",
        "analysis",
        "gap",
        "live",
        "bench",
        "sweep",
    },
    "transport": {
        "protocol",
        "runner",
        "recorder",
        "device",
        "cli",
        "log",
        "analysis",
        "gap",
        "live",
        "bench",
        "sweep",
    },
    "emulator": {
        "transport",
        "runner",
        "recorder",
        "device",
        "cli",
        "log",
        "analysis",
        "gap",
        "live",
        "bench",
        "sweep",
    },
    "analysis": {"protocol", "transport", "emulator", "runner", "device", "cli"},
    "runner": {"transport", "emulator", "device", "cli", "analysis"},
    "recorder": {"transport", "emulator", "device", "cli", "analysis", "runner"},
    "wire_blocks": {"transport", "emulator", "device", "cli", "analysis", "runner", "recorder"},
    "device": {"cli", "runner", "analysis"},
    "bench": {"cli"},
    "live": {"cli", "runner", "device"},
}


def _modules():
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG).with_suffix("")
        parts = rel.parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        yield path, parts


def _imports(path: Path) -> set[str]:
    """The pmsm_hil packages (first component under pmsm_hil) that a module imports."""
    out = set()
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
            if node.module == "pmsm_hil":
                names = [f"pmsm_hil.{a.name}" for a in node.names]
        for n in names:
            if n.startswith("pmsm_hil."):
                out.add(n.split(".")[1])
    return out


def test_the_layering_table_names_real_packages():
    top = {
        p.stem if p.is_file() else p.name
        for p in PKG.iterdir()
        if (p.is_dir() and (p / "__init__.py").exists()) or p.suffix == ".py"
    }
    for pkg, _bad in FORBIDDEN.items():
        assert pkg in top, pkg


@pytest.mark.parametrize("pkg", sorted(FORBIDDEN))
def test_imports_point_in_the_allowed_direction(pkg):
    bad = FORBIDDEN[pkg]
    offenders = []
    for path, parts in _modules():
        if not parts or parts[0] != pkg:
            continue
        hits = {m for m in _imports(path) if m != pkg and ("*" in bad or m in bad)}
        if hits:
            offenders.append(f"{path.relative_to(PKG.parent)} imports {sorted(hits)}")
    assert not offenders, "\n".join(offenders)


def test_the_checker_sees_imports_inside_functions(tmp_path):
    mod = tmp_path / "m.py"
    mod.write_text(
        "def f():\n    from pmsm_hil.transport.base import TransportError\n"
        "import pmsm_hil.protocol.codec\n"
    )
    assert _imports(mod) == {"transport", "protocol"}


def test_the_cli_starts_without_the_heavy_libraries():
    """`pmsm-hil` parses its arguments before it imports pydantic, numpy, yaml or Dask: every
    command's start pays for what the parser's modules import at their top (a constant imported
    from the sweep's planner once made every start 0.35 s slower)."""
    import subprocess
    import sys

    code = (
        "import sys, pmsm_hil.cli.main; "
        "print(sorted(m for m in ('pydantic', 'numpy', 'yaml', 'dask', 'rich') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout
