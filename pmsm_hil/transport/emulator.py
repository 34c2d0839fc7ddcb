"""Starts a local emulator process (`pmsm-hil emulate`) and talks to it over its pty."""

from __future__ import annotations

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
    ):
        args = ["--motor", str(motor_path), "--seed", str(seed), "--baud", str(baud)]
        if pace:
            args += ["--pace", repr(float(pace))]
        if corrupt_ppm:
            args += ["--corrupt-ppm", str(corrupt_ppm)]
        if rig_path:
            args += ["--rig", str(rig_path)]
        self.proc = emu_process.start(args)
        path = emu_process.wait_for_announcement(self.proc, "serial: ", start_timeout_s)
        super().__init__(path, baud)
        self.name = f"emulator {path} @ {baud}"

    def close(self) -> None:
        if hasattr(self, "_ser"):
            super().close()
        emu_process.stop(self.proc)
