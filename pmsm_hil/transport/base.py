"""The transport interface: a byte pipe to the device, whatever carries it."""
from __future__ import annotations

from typing import Protocol


class TransportError(Exception):
    """The link cannot be opened or has dropped; the message says which port and why."""


class TransportSpecError(TransportError):
    """The user named a port or interface in a form that cannot be meant (bad input, exit 2)."""


class Transport(Protocol):
    name: str          # e.g. "serial /dev/ttyUSB0 @ 921600"
    bit_rate: float    # the link's bit rate, for the live view's link-use figure

    def write(self, data: bytes) -> None: ...

    def read(self, timeout_s: float) -> bytes:
        """Whatever arrived, waiting at most timeout_s for the first octet (b"" if none)."""
        ...

    def close(self) -> None: ...
