"""A protocol session with one device: hello/identify with the version and schema check, commands
with acknowledgement and retry, and a stream of decoded frames for everything else."""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from pmsm_hil.errors import DeviceError, TransportError
from pmsm_hil.protocol import generated as gen
from pmsm_hil.protocol.link import as_link

if TYPE_CHECKING:
    from pmsm_hil.protocol.can_link import CanLink
    from pmsm_hil.protocol.link import ByteTransport, SerialLink

ACK_TEXT = {v: k for k, v in gen.ENUMS["ack_status"].items()}
BOARD_NAMES = {v: k for k, v in gen.ENUMS["board"].items()}
# the link decoders' (serial and CAN) counts of damaged or missing frames
_ERROR_COUNTERS = (
    "crc_errors",
    "cobs_errors",
    "len_errors",
    "short_errors",
    "unknown_id",
    "order_errors",
    "seq_gaps",
)


@dataclass
class Identity:
    proto_version: int
    schema_hash: int
    fw_version: str
    board: str
    tx_buf_octets: int
    capture_len: int


class Session:
    def __init__(self, transport: ByteTransport | SerialLink | CanLink):
        """`transport`: a link (serial or CAN), or a byte transport that gets the serial framing."""
        self.link = as_link(transport)
        self.t = self.link  # .name for messages
        self.decoder = self.link.decoder  # frame counters (link statistics)
        self.inbox: deque = deque()  # frames that arrived while waiting for something else
        self._seq = 0
        self.identity: Identity | None = None
        self.capture_missing: list[int] = []  # capture chunks that did not arrive (read_capture)
        self.capture_rejected = 0  # capture chunks refused as corrupt
        self.capture_abandoned = False  # read_capture gave up on a link that carried nothing

    # ------------------------------------------------------------------ sending
    def send(self, name: str, **fields: Any) -> int:
        seq = self._seq
        self._seq = (self._seq + 1) & 0xFF
        self.link.send(name, seq, **fields)
        return seq

    # ------------------------------------------------------------------ receiving
    def poll(self, timeout_s: float = 0.0) -> list:
        """Frames received now (plus any held back), waiting at most timeout_s for data."""
        frames = list(self.inbox)
        self.inbox.clear()
        frames.extend(self.link.poll(0.0 if frames else timeout_s))
        return frames

    def _wait_for(self, match, timeout_s: float, drop_before: bool = False):
        """The first frame that ``match``es, or None after ``timeout_s``; the others are kept, in
        order, for the caller's next poll(). ``drop_before``: the frames before the match (and
        those held from before) are dropped instead."""
        deadline = time.monotonic() + timeout_s
        held: list = []
        found = None
        while found is None:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            for fr in self.link.poll(min(left, 0.05)):
                if found is None and match(fr):
                    found = fr
                    if drop_before:
                        self.inbox.clear()
                        held.clear()
                else:
                    held.append(fr)
        self.inbox.extend(held)
        return found

    def request(self, name: str, timeout_s: float = 0.5, retries: int = 3, **fields: Any) -> None:
        """Send a command and wait for its ack; retried on silence, DeviceError on refusal."""
        msg_id = gen.BY_NAME[name].id
        for _attempt in range(retries):
            seq = self.send(name, **fields)
            fr = self._wait_for(
                lambda f, seq=seq: (
                    f.name == "ack" and f.fields["cmd_id"] == msg_id and f.fields["cmd_seq"] == seq
                ),
                timeout_s,
            )
            if fr is None:
                continue
            status = fr.fields["status"]
            if status != gen.ENUMS["ack_status"]["ok"]:
                raise DeviceError(
                    f"device refused {name} ({ACK_TEXT.get(status, status)})"
                    + (f": {fields}" if fields else "")
                )
            return
        raise DeviceError(
            f"device did not acknowledge {name} after {retries} tries "
            f"({timeout_s:.1f} s each) on {self.t.name}"
        )

    def hello(self, timeout_s: float = 2.0) -> Identity:
        """Identify the device; refuse a protocol version or schema mismatch, naming both.

        What arrived before the device's identify belongs to no session of this host: the output
        of a run whose host was killed, left in the port's buffer (telemetry, its heartbeat-lost
        fault, acks of its commands) and the torn frame at its start. Those frames are dropped
        and the link's error counts start again from the identify, so that the run's log, summary
        and link statistics hold only its own session."""
        for _attempt in range(2):
            self.send("hello", host_proto_version=gen.PROTOCOL_VERSION)
            fr = self._wait_for(lambda f: f.name == "identify", timeout_s / 2, drop_before=True)
            if fr is not None:
                break
        else:
            raise DeviceError(
                f"no answer to hello within {timeout_s:.1f} s on {self.t.name}: "
                f"is the device powered, the port right and the baud rate matching?"
            )
        f = fr.fields
        if f["proto_version"] != gen.PROTOCOL_VERSION or f["schema_hash"] != gen.SCHEMA_HASH:
            raise DeviceError(
                f"protocol mismatch: device speaks version {f['proto_version']} schema "
                f"{f['schema_hash']:08x}, this host speaks version {gen.PROTOCOL_VERSION} schema "
                f"{gen.SCHEMA_HASH:08x}; flash the firmware built from this tree or use the host "
                f"that matches the firmware"
            )
        for counter in _ERROR_COUNTERS:
            if hasattr(self.decoder, counter):
                setattr(self.decoder, counter, 0)
        self.identity = Identity(
            proto_version=f["proto_version"],
            schema_hash=f["schema_hash"],
            fw_version=f"{f['fw_major']}.{f['fw_minor']}.{f['fw_patch']}",
            board=BOARD_NAMES.get(f["board"], str(f["board"])),
            tx_buf_octets=f["tx_buf_octets"],
            capture_len=f["capture_len"],
        )
        return self.identity

    def read_capture(
        self,
        count: int,
        timeout_s: float = 0.5,
        retries: int = 3,
        give_up_after: int = 4,
        window: int | None = None,
    ) -> list[dict]:
        """Upload the capture buffer chunk by chunk, retrying lost chunks.

        Up to ``window`` chunks are asked for before the first answer is waited for (default
        ``capture_window``: what the device's transmit buffer holds twice over), so that an upload
        costs one round trip per window rather than per chunk: on a USB-UART with a millisecond's
        latency, or a CAN link, that is most of its time. A chunk that does not arrive after
        `retries` tries is skipped (its offset is listed in `capture_missing`) and the upload goes
        on: what arrived is kept. After `give_up_after` chunks in a row have not arrived the link
        is not carrying the upload: the rest is listed as missing too and the upload ends
        (`capture_abandoned`), rather than waiting out every chunk. A chunk whose `n_valid`
        exceeds its capacity or what is left of the buffer is refused as corrupt (counted in
        `capture_rejected`) and asked for again. A chunk of no samples ends the buffer there.

        The wait for a chunk adapts to the link: `timeout_s` until two chunks have arrived, then
        four times the slowest of the last eight round trips (at least 50 ms, at most
        `timeout_s`), so a lossy link costs retries, not half-second waits."""
        self.capture_missing = []
        self.capture_rejected = 0
        self.capture_abandoned = False
        per_chunk = next(f.count for f in gen.BY_NAME["capture_chunk"].fields if f.name == "i_a_a")
        window = max(1, window if window is not None else self.capture_window())
        todo = deque(range(0, count, per_chunk))  # offsets not asked for yet
        asked: dict[int, tuple[float, int]] = {}  # offset -> (when last asked, tries)
        got: dict[int, dict] = {}
        missed_in_a_row = 0
        rtts: deque[float] = deque(maxlen=8)
        end = count  # a chunk of no samples moves the end there
        held: list = []

        def ask(offset: int, tries: int) -> None:
            asked[offset] = (time.monotonic(), tries)
            self.send("capture_read", offset=offset)

        try:
            while todo or asked:
                if missed_in_a_row >= give_up_after:
                    rest = sorted([*asked, *todo])
                    self.capture_missing.extend(o for o in rest if o < end)
                    self.capture_abandoned = True
                    break
                while todo and len(asked) < window:
                    ask(todo.popleft(), 1)
                wait_s = min(timeout_s, max(0.05, 4.0 * max(rtts))) if len(rtts) >= 2 else timeout_s
                now = time.monotonic()
                first = min(t for t, _ in asked.values()) if asked else now
                for fr in self.link.poll(max(0.0, min(first + wait_s - now, 0.05))):
                    off = fr.fields.get("offset") if fr.name == "capture_chunk" else None
                    if off not in asked:
                        held.append(fr)  # kept, in order, for the caller's next poll()
                        continue
                    sent, tries = asked.pop(off)
                    rtts.append(time.monotonic() - sent)
                    n = fr.fields["n_valid"]
                    if n > min(per_chunk, count - off):
                        self.capture_rejected += 1
                        if not self._retry_or_miss(off, tries, retries, ask):
                            missed_in_a_row += 1
                        continue
                    missed_in_a_row = 0
                    if n == 0:  # nothing from here on: nor ask for it
                        if off < end:
                            end = off
                            todo = deque(o for o in todo if o < end)
                            for o in [o for o in asked if o >= end]:
                                del asked[o]
                        continue
                    got[off] = fr.fields
                now = time.monotonic()
                for off, (sent, tries) in sorted(asked.items()):
                    if now - sent >= wait_s:
                        del asked[off]
                        if not self._retry_or_miss(off, tries, retries, ask):
                            missed_in_a_row += 1
        finally:
            self.inbox.extend(held)
        self.capture_missing = sorted(o for o in self.capture_missing if o < end)
        return [got[o] for o in sorted(got) if o < end]

    def _retry_or_miss(self, offset: int, tries: int, retries: int, ask) -> bool:
        """Ask for the chunk at ``offset`` again (True), or list it as missing after ``retries``."""
        if tries < retries:
            ask(offset, tries + 1)
            return True
        self.capture_missing.append(offset)
        return False

    def capture_window(self) -> int:
        """Chunks asked for at once: the link's own figure (CAN: its transmit queue's frames), else
        as many as half the device's transmit buffer holds (`identify`'s tx_buf_octets), else 1."""
        own = getattr(self.link, "capture_window", None)
        if isinstance(own, int):
            return own
        if self.identity is None:
            return 1
        raw = gen.BY_NAME["capture_chunk"].length + 4  # id, seq, payload, CRC
        encoded = raw + raw // 254 + 2  # COBS and the delimiter
        return max(1, min(8, (self.identity.tx_buf_octets // 2) // encoded))


__all__ = ["DeviceError", "Identity", "Session", "TransportError"]
