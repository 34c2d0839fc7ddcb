"""Running `pmsm-hil` as a user does, in a fresh interpreter: the tests that check exit codes,
stdout and stderr of whole commands."""

from __future__ import annotations

import subprocess
import sys

CLI = [sys.executable, "-m", "pmsm_hil.cli.main"]


def cli(*args, timeout: float = 180, **kw) -> subprocess.CompletedProcess:
    """``pmsm-hil ARGS`` (each turned into text), its output captured as text."""
    return subprocess.run(
        [*CLI, *map(str, args)], capture_output=True, text=True, timeout=timeout, **kw
    )
