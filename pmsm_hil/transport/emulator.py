"""Starts a local emulator process (`pmsm-hil emulate`) and talks to it over its pty."""

from __future__ import annotations

import json
import os
import subprocess
import tempfile

from pmsm_hil.emulator import process as emu_process
from pmsm_hil.errors import TransportError
from pmsm_hil.transport.serial_port import SerialTransport


class EmulatorTransport(SerialTransport):
    def __init__(
        self,
        motor_path: str,
        rig_path: str | None,
        seed: int,
        baud: int,
        start_timeout_s: float = 20.0,
        corrupt_ppm: float = 0.0,
        pace: float | None = None,
        settings: dict[str, float] | None = None,
        plant: str = "",
    ):
        """``settings``: the sim board's settings as built from the motor and rig files
        (emulator_settings): given to the child, which then reads no file."""
        args = ["--motor", str(motor_path), "--seed", str(seed), "--baud", str(baud)]
        if pace:
            args += ["--pace", repr(float(pace))]
        if corrupt_ppm:
            args += ["--corrupt-ppm", str(corrupt_ppm)]
        if rig_path:
            args += ["--rig", str(rig_path)]
        self.proc: subprocess.Popen | None = None
        path = ""
        try:
            path = self._start(args, settings, plant, start_timeout_s)
            super().__init__(path, baud)
        except OSError as e:  # the OS refused a process, a pipe or a file: a link that cannot open
            self._stop_child()
            what = f"'s pty {path} could not be opened" if path else " could not be started"
            raise TransportError(f"the emulator{what}: {e.strerror or e} (errno {e.errno})") from e
        except BaseException:  # its pty could not be opened, Ctrl-C: no child left behind
            self._stop_child()
            raise
        self.name = f"emulator {path} @ {baud}"

    def _start(
        self, args: list[str], settings: dict | None, plant: str, start_timeout_s: float
    ) -> str:
        """Start the child with ``args`` (and the settings in a file it reads at its start):
        where it serves."""
        given = None
        if settings is not None:
            fd, given = tempfile.mkstemp(prefix="pmsm-hil-emulator-", suffix=".json")
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump({"settings": settings, "plant": plant}, f)
            args += ["--settings-file", given]
        try:
            self.proc = emu_process.start(args)
            return emu_process.wait_for_announcement(self.proc, "serial: ", start_timeout_s)
        finally:
            if given is not None:  # read by the child before it announces itself
                os.unlink(given)

    def _stop_child(self) -> None:
        if self.proc is not None:
            emu_process.stop(self.proc)

    def close(self) -> None:
        if hasattr(self, "_ser"):
            super().close()
        self._stop_child()
