"""Starts a local emulator process (`pmsm-hil emulate`) and talks to it over its pty."""

from __future__ import annotations

import json
import os
import tempfile

from pmsm_hil.emulator import process as emu_process
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
        given = None
        if settings is not None:
            fd, given = tempfile.mkstemp(prefix="pmsm-hil-emulator-", suffix=".json")
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump({"settings": settings, "plant": plant}, f)
            args += ["--settings-file", given]
        if pace:
            args += ["--pace", repr(float(pace))]
        if corrupt_ppm:
            args += ["--corrupt-ppm", str(corrupt_ppm)]
        if rig_path:
            args += ["--rig", str(rig_path)]
        try:
            self.proc = emu_process.start(args)
            path = emu_process.wait_for_announcement(self.proc, "serial: ", start_timeout_s)
        finally:
            if given is not None:  # read by the child before it announces itself
                os.unlink(given)
        super().__init__(path, baud)
        self.name = f"emulator {path} @ {baud}"

    def close(self) -> None:
        if hasattr(self, "_ser"):
            super().close()
        emu_process.stop(self.proc)
