"""In-process loopback transport: the emulated device in this process, no pty, no subprocess.

The device runs only when the host reads, a chunk of control periods at a time, so device time
never runs away from the host; used by tests, benchmarks and the shared transport test suite."""

from __future__ import annotations

from pmsm_hil.emulator.fwlib import EmulatedDevice


class InProcessTransport:
    def __init__(
        self,
        settings: dict[str, float],
        chunk_ticks: int = 400,
        device: EmulatedDevice | None = None,
    ):
        self.dev = device or EmulatedDevice(settings)
        self.chunk_ticks = chunk_ticks
        self.bit_rate = float(settings.get("baud", 921600))
        self.name = "in-process emulator"
        self.closed = False

    def write(self, data: bytes) -> None:
        self.dev.rx(data)

    def read(self, timeout_s: float) -> bytes:
        _, out = self.dev.run(self.chunk_ticks if self.dev.active else 0)
        return out

    def close(self) -> None:
        self.closed = True
