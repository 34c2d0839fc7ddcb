"""In-process loopback transport: the emulated device in this process, no pty, no subprocess.

The device runs only when the host reads, a chunk of control periods at a time, so device time
never runs away from the host; used by tests, benchmarks and the shared transport test suite.
`noise_d2h` / `noise_h2d` (e.g. pmsm_hil.emulator.link_noise.LinkNoise) are applied to the octets
on their way, as a noisy line would (benchmarks/link_faults.py)."""

from __future__ import annotations

from collections.abc import Callable

from pmsm_hil.emulator.fwlib import EmulatedDevice


class InProcessTransport:
    def __init__(
        self,
        settings: dict[str, float],
        chunk_ticks: int = 400,
        device: EmulatedDevice | None = None,
        noise_d2h: Callable[[bytes], bytes] | None = None,
        noise_h2d: Callable[[bytes], bytes] | None = None,
    ):
        self.dev = device or EmulatedDevice(settings)
        self.noise_d2h, self.noise_h2d = noise_d2h, noise_h2d
        self.chunk_ticks = chunk_ticks
        self.bit_rate = float(settings.get("baud", 921600))
        self.name = "in-process emulator"
        self.closed = False

    def write(self, data: bytes) -> None:
        self.dev.rx(self.noise_h2d(data) if self.noise_h2d is not None else data)

    def read(self, timeout_s: float) -> bytes:
        _, out = self.dev.run(self.chunk_ticks if self.dev.active else 0)
        return self.noise_d2h(out) if self.noise_d2h is not None and out else out

    def close(self) -> None:
        self.closed = True
