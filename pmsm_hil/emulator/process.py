"""The emulator as a child process: start `python -P -m pmsm_hil.emulator ...`, wait for the line
in which it announces where it serves (`serial: PATH` or `can: SPEC`), stop it.

- `-P` (safe path): the working directory is not put on the child's import path, so it imports the
  installed package even when started from a source checkout (whose tree has no compiled `_fw`).
- A session of its own: the terminal's Ctrl-C (SIGINT to the foreground process group) reaches the
  host only, which stops the motor through the link and then ends the child itself.
"""

from __future__ import annotations

import os
import select
import subprocess
import sys
import time

from pmsm_hil.errors import TransportError


def start(args: list[str]) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-P", "-m", "pmsm_hil.emulator", "--exit-with-parent", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        start_new_session=True,
    )


def wait_for_announcement(proc: subprocess.Popen, prefix: str, timeout_s: float) -> str:
    """The text after `prefix` on the emulator's first line that starts with it."""
    deadline = time.monotonic() + timeout_s
    seen = b""
    assert proc.stdout is not None and proc.stderr is not None  # started with both piped
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            err = proc.stderr.read().decode(errors="replace").strip()
            raise TransportError(f"the emulator exited before serving: {err[-2000:]}")
        ready, _, _ = select.select([proc.stdout], [], [], 0.1)
        if ready:
            seen += os.read(proc.stdout.fileno(), 4096)
            for line in seen.decode(errors="replace").splitlines():
                if line.startswith(prefix):
                    return line[len(prefix) :].strip()
    stop(proc)
    raise TransportError(f"the emulator did not start within {timeout_s:.0f} s")


def stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=3)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
