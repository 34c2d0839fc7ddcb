"""Links: a transport plus the framing that carries protocol messages over it.

A link sends a message (name, seq, fields) and returns the decoded frames that arrived. The serial
link frames with COBS + CRC-16 (docs/protocol.md) over any byte transport (a UART, the emulator's
pty, the in-process emulator); the CAN link maps messages onto CAN frames. The session above sees
no difference."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

from pmsm_hil.protocol import codec

if TYPE_CHECKING:
    from pmsm_hil.protocol.can_link import CanLink


class ByteTransport(Protocol):
    """What the serial link needs of a byte pipe (pmsm_hil.transport.base.Transport)."""

    name: str

    def write(self, data: bytes) -> None: ...

    def read(self, timeout_s: float) -> bytes: ...

    def close(self) -> None: ...


class SerialLink:
    """Protocol messages over a byte transport."""

    def __init__(self, transport: ByteTransport):
        self.transport = transport
        self.decoder = codec.FrameDecoder()
        self.name = transport.name
        self.bit_rate = getattr(transport, "bit_rate", 0.0)

    def send(self, name: str, seq: int, **fields: Any) -> None:
        self.transport.write(codec.encode(name, seq, **fields))

    def poll(self, timeout_s: float) -> list:
        data = self.transport.read(timeout_s)
        return self.decoder.feed(data) if data else []

    def close(self) -> None:
        self.transport.close()


def as_link(transport_or_link: ByteTransport | SerialLink | CanLink) -> SerialLink | CanLink:
    """A link for a byte transport, or the link itself."""
    if hasattr(transport_or_link, "poll") and hasattr(transport_or_link, "send"):
        return transport_or_link  # type: ignore[return-value]  # a link, by its methods
    return SerialLink(transport_or_link)
