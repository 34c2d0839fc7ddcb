"""Serial codec: payloads from the generated tables, and COBS/CRC-16 framing (docs/protocol.md).

    frame = COBS(id, seq, payload..., crc_hi, crc_lo) 0x00
    CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over id, seq and payload, high octet first.

Scaled fields are SI floats on this side: wire = floor(value / scale + 0.5), saturated to the wire
type's range, NaN -> 0 (the same rule as the firmware's proto_*_pack). Arrays are sequences in, tuples
out. The decoder works on whole buffers (split at 0x00, C-implemented COBS and CRC) for speed.
"""

from __future__ import annotations

import math
from binascii import crc_hqx
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from cobs.cobs import DecodeError as _CobsDecodeError
from cobs.cobs import decode as _cobs_decode
from cobs.cobs import encode as _cobs_encode

from .generated import BY_ID, BY_NAME, MAX_PAYLOAD, WIRE_TYPES, FieldSpec, MessageSpec

MAX_RAW = MAX_PAYLOAD + 4  # id, seq, payload, crc_hi, crc_lo
MAX_ENCODED = MAX_RAW + MAX_RAW // 254 + 1  # COBS of the longest raw frame, without the delimiter
CRC_INIT = 0xFFFF


class ProtocolError(ValueError):
    """A message or field that the protocol does not know, or a value that does not fit."""


class Frame:
    """A checked frame: id, sequence number, message name and its fields in SI units.

    The decoder keeps the payload octets and decodes the fields when they are first asked for:
    the recorder writes the busiest messages to the log from the octets (pmsm_hil.recorder)."""

    __slots__ = ("_fields", "msg_id", "name", "payload", "seq")

    def __init__(
        self,
        msg_id: int,
        seq: int,
        name: str,
        fields: dict[str, Any] | None = None,
        payload: bytes = b"",
    ):
        self.msg_id, self.seq, self.name = msg_id, seq, name
        self._fields, self.payload = fields, payload

    @property
    def fields(self) -> dict[str, Any]:
        f = self._fields
        if f is None:
            f = self._fields = _DECODERS[self.msg_id][2](self.payload)
        return f

    def _tuple(self) -> tuple[int, int, str, dict[str, Any]]:
        return (self.msg_id, self.seq, self.name, self.fields)

    def __iter__(self) -> Iterator[Any]:
        return iter(self._tuple())

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Frame):
            return self._tuple() == other._tuple()
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]  # its fields are a dict

    def __repr__(self) -> str:
        return (
            f"Frame(msg_id={self.msg_id}, seq={self.seq}, name={self.name!r}, "
            f"fields={self.fields!r})"
        )


def spec_of(name_or_id: str | int) -> MessageSpec:
    spec = BY_NAME.get(name_or_id) if isinstance(name_or_id, str) else BY_ID.get(name_or_id)
    if spec is None:
        known = ", ".join(sorted(BY_NAME))
        shown = f"0x{name_or_id:02X}" if isinstance(name_or_id, int) else repr(name_or_id)
        raise ProtocolError(f"unknown message {shown} (known: {known})")
    return spec


# ----------------------------------------------------------------------------------- encoding


def _quantiser(scale: float, wire_type: str) -> Callable[[Any], int]:
    _, _, lo_opt, hi_opt = WIRE_TYPES[wire_type]
    assert lo_opt is not None and hi_opt is not None  # integer wire types have limits
    lo, hi = lo_opt, hi_opt
    inv = 1.0 / scale  # multiply by the reciprocal, as the firmware does

    def quantise(value: Any) -> int:
        x = float(value) * inv
        if math.isnan(x):
            return 0
        if x >= hi:
            return hi
        if x <= lo:
            return lo
        return math.floor(x + 0.5)

    return quantise


def quantise(value: float, scale: float, wire_type: str) -> int:
    """SI value -> wire integer: round half up, saturate to the type's range, NaN -> 0."""
    return _quantiser(scale, wire_type)(value)


def _field_encoder(msg: str, f: FieldSpec) -> Callable[[Any], int | float]:
    code, _, lo, hi = WIRE_TYPES[f.type]
    where = f"{msg}.{f.name}"
    if f.scale is not None:
        return _quantiser(f.scale, f.type)
    if code == "f":
        return float

    def integer(v: Any) -> int:
        try:
            n = v.__index__()
        except AttributeError:
            raise ProtocolError(f"{where}: expected an integer, got {v!r}") from None
        if not lo <= n <= hi:
            raise ProtocolError(f"{where}={n} is outside the {f.type} range {lo}..{hi}")
        return n

    return integer


_ENCODERS: dict[str, list[tuple[FieldSpec, Callable[[Any], int | float]]]] = {
    spec.name: [(f, _field_encoder(spec.name, f)) for f in spec.fields] for spec in BY_ID.values()
}


def encode_payload(name_or_id: str | int, **fields: Any) -> bytes:
    """The payload octets of one message; every field must be given, in SI units."""
    spec = spec_of(name_or_id)
    missing = [n for n in spec.names if n not in fields]
    unknown = [n for n in fields if n not in spec.names]
    if missing or unknown:
        raise ProtocolError(f"{spec.name}: missing fields {missing}, unknown fields {unknown}")
    flat: list[int | float] = []
    for f, conv in _ENCODERS[spec.name]:
        v = fields[f.name]
        if f.count == 1:
            flat.append(conv(v))
            continue
        if len(v) != f.count:
            raise ProtocolError(f"{spec.name}.{f.name}: expected {f.count} values, got {len(v)}")
        flat.extend(conv(x) for x in v)
    try:
        return spec.struct.pack(*flat)
    except (OverflowError, ValueError) as e:  # struct.error is a ValueError; f32 overflow
        raise ProtocolError(f"{spec.name}: {e}") from None


def encode_frame(msg_id: int, seq: int, payload: bytes) -> bytes:
    """COBS(id, seq, payload, crc_hi, crc_lo) + 0x00 for an already packed payload."""
    if not 0 <= msg_id <= 0xFF or not 0 <= seq <= 0xFF:
        raise ProtocolError(f"msg_id 0x{msg_id:X} and seq {seq} must be octets (0..255)")
    if len(payload) > MAX_PAYLOAD:
        raise ProtocolError(f"payload of {len(payload)} octets exceeds MAX_PAYLOAD={MAX_PAYLOAD}")
    raw = bytes((msg_id, seq)) + payload
    return _cobs_encode(raw + crc_hqx(raw, CRC_INIT).to_bytes(2, "big")) + b"\x00"


def encode(name_or_id: str | int, seq: int, **fields: Any) -> bytes:
    """A whole frame with its delimiter; fields in SI units, arrays as sequences."""
    spec = spec_of(name_or_id)
    return encode_frame(spec.id, seq, encode_payload(spec.id, **fields))


# ----------------------------------------------------------------------------------- decoding


def _payload_decoder(spec: MessageSpec) -> Callable[[bytes], dict[str, Any]]:
    """A decoder specialised to one message: one struct unpack and a dict display, compiled once.

    Generating the source (as collections.namedtuple does) is twice as fast as a generic loop over
    the fields, which matters at tens of thousands of frames per second."""
    items, i = [], 0
    for f in spec.fields:
        scaled = [
            f"v[{k}]" + ("" if f.scale is None else f" * {f.scale!r}")
            for k in range(i, i + f.count)
        ]
        items.append(f"{f.name!r}: " + (scaled[0] if f.count == 1 else f"({', '.join(scaled)},)"))
        i += f.count
    body = "    v = unpack(p)\n" if spec.fields else ""
    src = f"def decode_{spec.name}(p):\n{body}    return {{{', '.join(items)}}}\n"
    namespace: dict[str, Any] = {"unpack": spec.struct.unpack}
    exec(compile(src, f"<codec {spec.name}>", "exec"), namespace)
    return namespace[f"decode_{spec.name}"]


_DECODERS: dict[int, tuple[str, int, Callable[[bytes], dict[str, Any]]]] = {
    spec.id: (spec.name, spec.length, _payload_decoder(spec)) for spec in BY_ID.values()
}
_LENGTHS: dict[int, int] = {spec.id: spec.length for spec in BY_ID.values()}


def decode_payload(msg_id: int, payload: bytes) -> dict[str, Any]:
    """Payload octets -> {field: value}; scaled fields as SI floats, arrays as tuples."""
    entry = _DECODERS.get(msg_id)
    if entry is None:
        raise ProtocolError(f"unknown message id 0x{msg_id:02X}")
    name, length, decode = entry
    if len(payload) != length:
        raise ProtocolError(f"{name}: payload of {len(payload)} octets, expected {length}")
    return decode(payload)


_NUMPY_TYPES = {"u8": "u1", "u16": "<u2", "u32": "<u4", "i16": "<i2", "i32": "<i4", "f32": "<f4"}


def decode_payloads(msg_id: int, payloads: Iterable[bytes]) -> dict[str, Any]:
    """Many payloads of one message -> {field: numpy array} (arrays get a second axis); vectorised."""
    import numpy as np

    spec = spec_of(msg_id)
    dtype = np.dtype(
        [(f.name, _NUMPY_TYPES[f.type], (f.count,) if f.count > 1 else ()) for f in spec.fields]
    )
    data = b"".join(payloads)
    if len(data) % max(spec.length, 1):
        raise ProtocolError(f"{spec.name}: payloads are not all {spec.length} octets long")
    rec = np.frombuffer(data, dtype=dtype)
    return {
        f.name: (rec[f.name] * f.scale if f.scale is not None else rec[f.name].copy())
        for f in spec.fields
    }


class FrameDecoder:
    """Streaming decoder: feed it octets as they arrive, get whole checked frames back.

    A frame is judged when its 0x00 delimiter arrives; a bad one is counted and dropped, and the
    decoder is in step again from the next 0x00 on. Octets before the first delimiter may be the tail
    of a frame sent before the port was opened and count as one bad frame.
    """

    def __init__(self) -> None:
        self._tail = b""  # octets after the last delimiter
        self._skipping = False  # the tail overflowed: drop octets up to the next delimiter
        self.frames_ok = 0  # good frames returned (by feed: those with a known id)
        self.crc_errors = 0
        self.cobs_errors = 0
        self.len_errors = 0  # too long, or a known id with the wrong payload length
        self.short_errors = 0  # fewer than 4 octets after COBS
        self.unknown_id = 0  # good frame but an id not in the protocol (feed only)
        self.seq_gaps = 0  # frames missing according to the sequence numbers
        self.octets = 0
        self._next_seq = -1  # sequence number expected next; -1 before the first frame

    @property
    def bad_frames(self) -> int:
        return self.crc_errors + self.cobs_errors + self.len_errors + self.short_errors

    def counters(self) -> dict[str, int]:
        return {
            k: getattr(self, k)
            for k in (
                "frames_ok",
                "crc_errors",
                "cobs_errors",
                "len_errors",
                "short_errors",
                "unknown_id",
                "seq_gaps",
                "octets",
            )
        }

    def feed_raw(self, data: bytes) -> list[tuple[int, int, bytes]]:
        """Octets in, [(msg_id, seq, payload)] out for every good frame: COBS and CRC good and, for a
        known id, the right payload length. Unknown ids pass (as in the firmware's parser).

        The length check matters: CRC-16/CCITT-FALSE cannot see 0x00 octets appended after the CRC,
        which a delimiter flipped to 0x01 produces."""
        self.octets += len(data)
        chunks = (self._tail + data if self._tail else bytes(data)).split(b"\x00")
        tail = chunks.pop()
        if self._skipping:
            if not chunks:
                self._tail = b""
                return []
            chunks[0] = b""
            self._skipping = False
        if len(tail) > MAX_ENCODED:
            self.len_errors += 1
            tail, self._skipping = b"", True
        self._tail = tail

        out: list[tuple[int, int, bytes]] = []
        append, lengths = out.append, _LENGTHS
        next_seq, gaps = self._next_seq, 0
        for chunk in chunks:
            if not chunk:
                continue
            try:
                raw = _cobs_decode(chunk)
            except _CobsDecodeError:
                self.cobs_errors += 1
                continue
            n = len(raw)
            if n < 4:
                self.short_errors += 1
            elif n > MAX_RAW:
                self.len_errors += 1
            elif crc_hqx(raw, CRC_INIT):
                self.crc_errors += 1
            elif lengths.get(raw[0], n - 4) != n - 4:
                self.len_errors += 1
            else:
                seq = raw[1]
                if seq != next_seq and next_seq >= 0:
                    gaps += (seq - next_seq) & 0xFF
                next_seq = (seq + 1) & 0xFF
                append((raw[0], seq, raw[2:-2]))
        self._next_seq = next_seq
        self.seq_gaps += gaps
        self.frames_ok += len(out)
        return out

    def feed(self, data: bytes) -> list[Frame]:
        """Octets in, decoded frames out (known ids with the right payload length only)."""
        frames: list[Frame] = []
        append = frames.append
        decoders = _DECODERS
        for msg_id, seq, payload in self.feed_raw(data):
            entry = decoders.get(msg_id)
            if entry is None:
                self.unknown_id += 1
                self.frames_ok -= 1
            else:
                append(Frame(msg_id, seq, entry[0], None, payload))
        return frames
