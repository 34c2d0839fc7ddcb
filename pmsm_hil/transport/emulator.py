"""Starts a local emulator process (`pmsm-hil emulate`) and talks to it over its pty."""
from __future__ import annotations

import os
import select
import subprocess
import sys
import time

from pmsm_hil.transport.base import TransportError
from pmsm_hil.transport.serial_port import SerialTransport


class EmulatorTransport(SerialTransport):
    def __init__(self, motor_path: str, rig_path: str | None, seed: int, baud: int,
                 start_timeout_s: float = 20.0, corrupt_ppm: float = 0.0):
        cmd = [sys.executable, "-m", "pmsm_hil.emulator", "--motor", str(motor_path),
               "--seed", str(seed), "--baud", str(baud)]
        if corrupt_ppm:
            cmd += ["--corrupt-ppm", str(corrupt_ppm)]
        if rig_path:
            cmd += ["--rig", str(rig_path)]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     stdin=subprocess.DEVNULL)
        path = self._wait_for_port(start_timeout_s)
        super().__init__(path, baud)
        self.name = f"emulator {path} @ {baud}"

    def _wait_for_port(self, timeout_s: float) -> str:
        deadline = time.monotonic() + timeout_s
        line = b""
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                err = self.proc.stderr.read().decode(errors="replace").strip()
                raise TransportError(f"the emulator exited before serving: {err[-2000:]}")
            r, _, _ = select.select([self.proc.stdout], [], [], 0.1)
            if r:
                line += os.read(self.proc.stdout.fileno(), 4096)
                for text in line.decode(errors="replace").splitlines():
                    if text.startswith("serial: "):
                        return text.split(" ", 1)[1].strip()
        self.close()
        raise TransportError(f"the emulator did not start within {timeout_s:.0f} s")

    def close(self) -> None:
        super_close = getattr(super(), "close", None)
        if hasattr(self, "_ser") and super_close:
            super_close()
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=3)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
