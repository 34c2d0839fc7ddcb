"""Protocol messages over CAN (docs/can.md): the host side of firmware/core/can_link.c.

    identifier = function << 4 | node
    direct message:  frame k on function base + k; frame 0 = [seq, fields...]; fields never straddle;
                     2+ frames: frame crc_frame ends with [crc_hi, crc_lo], the CRC-16 below
    transfer:        header [0, msg_id, seq, len, crc_hi, crc_lo], data [index 1.., <= 7 octets]
                     CRC-16/CCITT-FALSE over msg_id, seq, payload (as the serial frame's)

`CanLink` presents the same interface as `SerialLink` (send, poll, decoder, name, bit_rate, close)
over any python-can bus, so the session, runner, live view and recorder work unchanged.
"""

from __future__ import annotations

import contextlib
import time
from binascii import crc_hqx
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any, Protocol

from pmsm_hil.errors import TransportError
from pmsm_hil.protocol import can_generated as cg
from pmsm_hil.protocol import codec
from pmsm_hil.protocol.generated import BY_ID

if TYPE_CHECKING:
    import can

CRC_INIT = 0xFFFF
NODE_MASK = (1 << cg.NODE_BITS) - 1
TRANSFER_TIMEOUT_S = 1.0  # an unfinished transfer older than this is dropped (and counted)
POLL_BATCH_S = 0.02  # at most this much wall time spent receiving in one poll


def frame_bits_nominal(dlc: int) -> int:
    """Bits of a base-format data frame without stuff bits, intermission included: 47 + 8 dlc."""
    return 47 + 8 * dlc


def can_id(func: int, node: int) -> int:
    return (func << cg.NODE_BITS) | node


def encode_message(
    name_or_id: str | int, seq: int, node: int = cg.NODE, **fields: Any
) -> list[tuple[int, bytes]]:
    """A message as [(identifier, data)], in the order they go on the bus."""
    spec = codec.spec_of(name_or_id)
    return encode_payload_frames(spec.id, seq, codec.encode_payload(spec.id, **fields), node)


def encode_payload_frames(
    msg_id: int, seq: int, payload: bytes, node: int = cg.NODE
) -> list[tuple[int, bytes]]:
    lay = cg.LAYOUTS.get(msg_id)
    if lay is None:
        raise codec.ProtocolError(f"message 0x{msg_id:02X} has no CAN layout")
    if lay.transfer:
        head = bytes((msg_id, seq & 0xFF)) + payload
        crc = crc_hqx(head, CRC_INIT)
        ident = can_id(lay.func, node)
        out = [(ident, bytes((0, msg_id, seq & 0xFF, len(payload), crc >> 8, crc & 0xFF)))]
        for k, at in enumerate(range(0, len(payload), cg.TRANSFER_DATA), start=1):
            out.append((ident, bytes((k,)) + payload[at : at + cg.TRANSFER_DATA]))
        return out
    data = bytes((seq & 0xFF,)) + payload
    crc_octets = b""
    if lay.crc_frame != cg.NO_CRC:  # the end-to-end check (docs/can.md)
        crc_octets = crc_hqx(bytes((msg_id, seq & 0xFF)) + payload, CRC_INIT).to_bytes(2, "big")
    out, at = [], 0
    for k, n in enumerate(lay.frame_octets):
        if k == lay.crc_frame:
            n -= cg.CRC_OCTETS
            out.append((can_id(lay.func + k, node), data[at : at + n] + crc_octets))
        else:
            out.append((can_id(lay.func + k, node), data[at : at + n]))
        at += n
    if at != len(data):
        raise codec.ProtocolError(
            f"{lay.name}: payload of {len(payload)} octets does not fit its layout"
        )
    return out


class CanDecoder:
    """Reassembles the device's frames into protocol frames, with counters like FrameDecoder's.

    `octets` counts octet-equivalents of bus time (nominal frame bits / 10, stuff bits not
    included), so that the live view's link-use figure (octets x 10 / bit rate) holds for CAN too."""

    def __init__(self, node: int = cg.NODE, direction: str = "d2h"):
        self.node = node
        self.direction = direction
        self.frames_ok = 0  # whole messages decoded
        self.crc_errors = 0  # transfers and multi-frame messages whose CRC fails (dropped)
        self.len_errors = 0  # frames of the wrong length
        self.order_errors = 0  # frames missing, repeated or out of place (message dropped)
        self.unknown_id = 0  # a function code, or a transferred message id, this host does not know
        self.cobs_errors = 0  # (serial only; kept for the common counters)
        self.short_errors = 0
        self.seq_gaps = 0
        self.octets = 0
        self.can_frames = 0
        self.bits = 0
        self._next_seq = -1
        self._slots: dict[int, list] = {}  # msg_id -> [next frame, seq, parts]
        self._xfer: list | None = None  # [msg_id, seq, len, crc, next, parts, t0]
        xfunc = cg.FUNC_TRANSFER_D2H if direction == "d2h" else cg.FUNC_TRANSFER_H2D
        self._xfer_id = can_id(xfunc, node)
        self._direct: dict[int, tuple] = {}  # identifier -> (msg_id, k, dlc, n_frames, crc_frame)
        for func, (msg_id, k) in cg.BY_FUNC.items():
            spec = BY_ID[msg_id]
            if spec.dir == direction:
                lay = cg.LAYOUTS[msg_id]
                self._direct[can_id(func, node)] = (
                    msg_id,
                    k,
                    lay.frame_octets[k],
                    len(lay.frame_octets),
                    lay.crc_frame,
                )
        self._decoders = codec._DECODERS

    @property
    def bad_frames(self) -> int:
        return self.crc_errors + self.len_errors + self.order_errors

    def counters(self) -> dict[str, int]:
        return {
            k: getattr(self, k)
            for k in (
                "frames_ok",
                "crc_errors",
                "len_errors",
                "order_errors",
                "unknown_id",
                "seq_gaps",
                "octets",
                "can_frames",
            )
        }

    def _done(self, out: list, msg_id: int, seq: int, payload: bytes) -> None:
        entry = self._decoders.get(msg_id)
        if entry is None:
            self.unknown_id += 1
            return
        if len(payload) != entry[1]:
            self.len_errors += 1
            return
        if self._next_seq >= 0 and seq != self._next_seq:
            self.seq_gaps += (seq - self._next_seq) & 0xFF
        self._next_seq = (seq + 1) & 0xFF
        self.frames_ok += 1
        out.append(codec.Frame(msg_id, seq, entry[0], entry[2](payload)))

    def feed(self, frames: Iterable[tuple[int, bytes | bytearray]]) -> list[codec.Frame]:
        out: list[codec.Frame] = []
        direct, slots = self._direct, self._slots
        for ident, data in frames:
            n = len(data)
            self.can_frames += 1
            self.bits += 47 + 8 * n
            if (ident & NODE_MASK) != self.node:
                continue
            d = direct.get(ident)
            if d is not None:
                msg_id, k, dlc, n_frames, crc_frame = d
                if n != dlc:
                    self.len_errors += 1
                    slots.pop(msg_id, None)
                    continue
                if k == 0:
                    if msg_id in slots:
                        self.order_errors += 1
                    if n_frames == 1:
                        slots.pop(msg_id, None)
                        self._done(out, msg_id, data[0], bytes(data[1:]))
                    else:
                        slots[msg_id] = [0, data[0], [], None]
                        self._part(slots[msg_id], bytes(data[1:]), 0, crc_frame)
                    continue
                slot = slots.get(msg_id)
                if slot is None or slot[0] != k:
                    self.order_errors += 1
                    slots.pop(msg_id, None)
                    continue
                self._part(slot, bytes(data), k, crc_frame)
                if k + 1 == n_frames:
                    del slots[msg_id]
                    payload = b"".join(slot[2])
                    # end to end: frames of two messages joined after a lost burst fail here
                    if crc_hqx(bytes((msg_id, slot[1])) + payload, CRC_INIT) != slot[3]:
                        self.crc_errors += 1
                        continue
                    self._done(out, msg_id, slot[1], payload)
            elif ident == self._xfer_id:
                self._feed_transfer(out, data)
            elif (ident >> cg.NODE_BITS) in cg.BY_FUNC or ident >> cg.NODE_BITS in (
                cg.FUNC_TRANSFER_D2H,
                cg.FUNC_TRANSFER_H2D,
            ):
                continue  # the other direction's frame (e.g. our own, echoed)
            else:
                self.unknown_id += 1
        self.octets = self.bits // 10
        return out

    @staticmethod
    def _part(slot: list, part: bytes, k: int, crc_frame: int) -> None:
        """Frame k's payload octets into slot [next frame, seq, parts, crc]."""
        if k == crc_frame:
            slot[3] = int.from_bytes(part[-cg.CRC_OCTETS :], "big")
            part = part[: -cg.CRC_OCTETS]
        slot[2].append(part)
        slot[0] = k + 1

    def _feed_transfer(self, out: list[codec.Frame], data: bytes | bytearray) -> None:
        now = time.monotonic()
        x = self._xfer
        if x is not None and now - x[6] > TRANSFER_TIMEOUT_S:
            self.order_errors += 1
            x = self._xfer = None
        if not data:
            self.len_errors += 1
            return
        if data[0] == 0:
            if x is not None:
                self.order_errors += 1
            if len(data) != cg.TRANSFER_HEADER:
                self.len_errors += 1
                self._xfer = None
                return
            self._xfer = x = [data[1], data[2], data[3], (data[4] << 8) | data[5], 1, [], now]
        else:
            if x is None or data[0] != x[4]:
                self.order_errors += 1
                self._xfer = None
                return
            got = sum(len(p) for p in x[5])
            want = min(cg.TRANSFER_DATA, x[2] - got)
            if len(data) != want + 1:
                self.len_errors += 1
                self._xfer = None
                return
            x[5].append(bytes(data[1:]))
            x[4] += 1
        payload = b"".join(x[5])
        if len(payload) < x[2]:
            return
        self._xfer = None
        if crc_hqx(bytes((x[0], x[1])) + payload, CRC_INIT) != x[3]:
            self.crc_errors += 1
            return
        self._done(out, x[0], x[1], payload)


class CanBus(Protocol):
    """What the link uses of a bus: python-can's ``BusABC`` or a bus like it (the in-process
    emulator's, which also has ``recv_batch``)."""

    def send(self, msg: can.Message, timeout: float | None = None) -> None: ...

    def recv(self, timeout: float | None = None) -> can.Message | None: ...

    def shutdown(self) -> None: ...


class CanLink:
    """Protocol messages over a python-can bus (any interface), as a link for the session."""

    # capture chunks asked for at once (Session.read_capture): a chunk is a transfer of 17 frames
    # (docs/can.md); two leave room in the firmware's 64-frame transmit queue for its status
    capture_window = 2

    def __init__(
        self,
        bus: CanBus,
        node: int = cg.NODE,
        bit_rate: float = cg.BITRATE,
        name: str | None = None,
        on_close: Callable[[], None] | None = None,
    ):
        self.bus = bus
        self.node = node
        self.bit_rate = float(bit_rate)
        self.name = name or f"CAN {getattr(bus, 'channel_info', bus)} node {node}"
        self.decoder = CanDecoder(node)
        self.sent_frames = 0
        self._on_close = on_close

    def send(self, name: str, seq: int, **fields: Any) -> None:
        import can

        for ident, data in encode_message(name, seq, self.node, **fields):
            try:
                self.bus.send(can.Message(arbitration_id=ident, data=data, is_extended_id=False))
            except (can.CanError, OSError) as e:
                raise TransportError(f"{self.name}: sending {name} failed: {e}") from e
            self.sent_frames += 1

    def poll(self, timeout_s: float) -> list[codec.Frame]:
        import can

        frames: list[tuple[int, bytes | bytearray]] = []
        batch = getattr(self.bus, "recv_batch", None)
        if batch is not None:  # the in-process bus: one chunk of device time per poll
            frames = batch()
            return self.decoder.feed(frames) if frames else []
        try:
            msg = self.bus.recv(timeout_s)
            # a bounded batch (frames and wall time), so that the caller's heartbeat is never late
            end = time.monotonic() + POLL_BATCH_S
            while msg is not None:
                if not (msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id):
                    frames.append((msg.arbitration_id, msg.data))
                if len(frames) >= 4096 or time.monotonic() > end:
                    break
                msg = self.bus.recv(0.0)
        except (can.CanError, OSError, ValueError) as e:
            raise TransportError(f"{self.name}: the link dropped: {e}") from e
        return self.decoder.feed(frames) if frames else []

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.bus.shutdown()
        if self._on_close is not None:
            self._on_close()
            self._on_close = None


# ------------------------------------------------------------------------------- link budget

STUFF_MARGIN = 1.10  # stuff bits: the budget assumes 10 % on top of the nominal frame bits
BUDGET_SHARE = 0.95  # share of the bus the telemetry plan may fill


def message_bits(name: str) -> float:
    """Bits on the bus for one message (all its frames), with the stuffing margin."""
    lay = cg.LAYOUTS[codec.spec_of(name).id]
    return STUFF_MARGIN * sum(frame_bits_nominal(n) for n in lay.frame_octets)


def can_budget(rates_hz: dict[str, float], bitrate: float = cg.BITRATE) -> dict:
    """Bits/s per stream for {message: rate} and the share of the bus they fill."""
    streams = {k: message_bits(k) * hz for k, hz in rates_hz.items() if hz}
    total = sum(streams.values())
    return {"streams": streams, "total_bits_s": total, "load": total / bitrate}


def can_fast_hz_max(
    other_rates_hz: dict[str, float], ts_s: float, bitrate: float = cg.BITRATE
) -> float:
    """The highest telem_fast rate (a whole number of control periods) that fits the budget next to
    the other streams."""
    left = BUDGET_SHARE * bitrate - can_budget(other_rates_hz, bitrate)["total_bits_s"]
    if left <= 0:
        return 0.0
    import math

    div = max(1, math.ceil(1.0 / (left / message_bits("telem_fast") * ts_s)))
    return 1.0 / (div * ts_s)
