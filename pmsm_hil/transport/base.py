"""The transport interface: a byte pipe to the device, whatever carries it."""

from __future__ import annotations

from typing import Protocol

from pmsm_hil.errors import TransportError, TransportSpecError

__all__ = ["Transport", "TransportError", "TransportSpecError"]


class Transport(Protocol):
    name: str  # e.g. "serial /dev/ttyUSB0 @ 921600"
    bit_rate: float  # the link's bit rate, for the live view's link-use figure

    def write(self, data: bytes) -> None: ...

    def read(self, timeout_s: float) -> bytes:
        """Whatever arrived, waiting at most timeout_s for the first octet (b"" if none)."""
        ...

    def close(self) -> None: ...
