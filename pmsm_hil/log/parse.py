"""The walk over an MCAP file's records for pmsm_hil.log.reader: top-level records one by one,
chunks opened only when they hold an asked topic (or channels not yet known), their messages
gathered through the chunks' message indexes and decoded in large batches (pmsm_hil.log.columns).
The chunks to open are read, decompressed and CRC-checked on a second thread a few ahead of the
one being decoded (docs/log-format.md, "Read-ahead")."""

from __future__ import annotations

import io
import os
import struct
import zlib
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np
from mcap import records as mr
from mcap.data_stream import ReadDataStream

from pmsm_hil.log.columns import DecodeError, decode_columns, gather, rows_at
from pmsm_hil.log.writer import MCAP_MAGIC

_R = TypeVar("_R")
_REC = struct.Struct("<BQ")
_U16 = struct.Struct("<H").unpack_from
_U32 = struct.Struct("<I").unpack_from
_U64 = struct.Struct("<Q").unpack_from
_MSG = struct.Struct("<HIQQ").unpack_from
_FOOTER = 1 + 8 + 20  # opcode, length, summary_start, summary_offset_start, crc
_BATCH_OCTETS = 8 << 20  # message data gathered across chunks before it is decoded at once
_AHEAD = 4  # chunks read, decompressed and CRC-checked ahead of the one being decoded
_MERGE = 4  # chunks decoded as one (_Parser._decode_merged) while _AHEAD more are read
_AHEAD_OCTETS = 32 << 20  # ... and at most this many compressed octets of them (large chunks)


_CHUNK_HEAD = struct.Struct("<QQQI")  # message start and end time, uncompressed size and CRC


def _decompressor(compression: str) -> Callable[[memoryview, int], bytes] | None:
    if compression == "zstd":
        import zstandard

        dctx = zstandard.ZstdDecompressor()
        return lambda data, size: dctx.decompress(data, max_output_size=size)
    if compression == "lz4":
        import lz4.frame

        return lambda data, size: lz4.frame.decompress(data)
    if compression == "":
        return lambda data, size: bytes(data)
    return None


def chunk_records(
    content: bytes, decompressors: dict[str, Callable[[memoryview, int], bytes] | None]
) -> bytes | str:
    """A chunk record's content (without opcode and length) -> its records, decompressed and
    CRC-checked; or, for a chunk that cannot be read, why (a problem of the log).
    ``decompressors``: by compression, made at the first chunk that needs one, kept for the
    next (a zstd context is not made per chunk)."""
    try:
        _t0, _t1, size, crc = _CHUNK_HEAD.unpack_from(content, 0)
        (n,) = _U32(content, 28)
        compression = bytes(content[32 : 32 + n]).decode()
        (length,) = _U64(content, 32 + n)
        data = memoryview(content)[40 + n : 40 + n + length]
        if len(data) != length:
            raise ValueError(f"{length - len(data)} octets of its data missing")
        if compression not in decompressors:
            decompressors[compression] = _decompressor(compression)
        decompress = decompressors[compression]
        if decompress is None:
            return f"chunk with unknown compression {compression!r} skipped"
        records = decompress(data, size)
        if crc and zlib.crc32(records) != crc:
            raise ValueError(f"CRC mismatch: {zlib.crc32(records):08x}, expected {crc:08x}")
    except Exception as e:  # a damaged chunk (CRC, compression): keep the rest of the file
        return f"chunk could not be read ({e}); skipped"
    if len(records) != size:
        return "chunk size mismatch; skipped"
    return records


def _read(cls: type[_R], content: bytes) -> _R:
    """One record's content (without opcode and length) parsed by the mcap library."""
    return cls.read(ReadDataStream(io.BytesIO(content)))  # type: ignore[attr-defined]


class LogFormatError(ValueError):
    """The file is not an MCAP file at all."""


@dataclass
class Attachment:
    name: str
    media_type: str
    data: bytes
    log_time_ns: int = 0
    create_time_ns: int = 0

    @property
    def text(self) -> str:
        return self.data.decode("utf-8")


@dataclass
class _Chan:
    id: int
    topic: str
    schema_id: int
    encoding: str
    metadata: dict
    wanted: bool = True  # decoded (asked for, or all topics asked for)
    fields: tuple | None = None  # the fields asked for (None: all)
    lts: list = field(default_factory=list)  # arrays of log times (uint64), per batch
    parts: dict = field(default_factory=dict)  # field -> decoded column arrays, per batch
    pending: list = field(default_factory=list)  # message data not decoded yet (uint8 arrays)
    pending_sizes: list = field(default_factory=list)  # their sizes (int64 arrays)
    pending_octets: int = 0
    expected: int = -1  # message count from the summary's statistics (-1: unknown)
    out: dict = field(default_factory=dict)  # field -> column allocated for `expected` messages
    out_lt: np.ndarray | None = None
    filled: int = 0  # messages decoded into `out`
    var_data: list = field(default_factory=list)  # bytes per message: schemas not flat
    error: str = ""  # why the messages cannot be decoded (raised by Log.topic)
    count: int = 0


@dataclass
class _Schema:
    id: int
    name: str
    encoding: str
    data: bytes


# ----------------------------------------------------------------------------------- parsing

Wanted = Mapping[str, "Iterable[str] | None"]
# called with each batch of an asked topic's messages as read: (topic, chunk octets, data starts,
# data sizes, log times); the octets are valid during the call only
Sink = Callable[[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray], None]


class _Parser:
    def __init__(self, log, f, size: int, wanted: Wanted | None, sink: Sink | None = None):
        self.log = log
        self.sink = sink
        self.f = f
        self.size = size
        self.wanted = (
            None
            if wanted is None
            else {t: (None if v is None else tuple(v)) for t, v in wanted.items()}
        )
        # every channel known up front (the summary of a finalised file): chunks may be skipped
        self.all_known = False
        self._decompressors: dict[str, Callable[[memoryview, int], bytes] | None] = {}
        # chunks being read and decompressed on a second thread (zstd, the CRC and the read
        # release the GIL), decoded here in file order
        self._ahead: deque[tuple[Future[bytes | str], dict[int, np.ndarray], int]] = deque()
        self._ahead_octets = 0
        self._pool: ThreadPoolExecutor | None = None
        self._own: io.BufferedReader | None = None

    def _at(self, p: int, n: int) -> bytes:
        self.f.seek(p)
        return self.f.read(n)

    # records that may appear in the data section, the summary or inside chunks
    def _schema(self, c) -> None:
        r = _read(mr.Schema, c)
        self.log._schemas[r.id] = _Schema(r.id, r.name, r.encoding, bytes(r.data))

    def _channel(self, c) -> None:
        r = _read(mr.Channel, c)
        if r.id in self.log._chans:
            return
        ch = _Chan(r.id, r.topic, r.schema_id, r.message_encoding, dict(r.metadata))
        if self.wanted is not None:
            ch.wanted = r.topic in self.wanted
            ch.fields = self.wanted.get(r.topic)
        self.log._chans[r.id] = ch
        self.log._by_topic.setdefault(r.topic, ch)

    def run(self) -> None:
        try:
            self._walk()
        finally:
            if self._pool is not None:
                self._pool.shutdown(wait=True, cancel_futures=True)
            if self._own is not None:
                self._own.close()

    def _walk(self) -> None:
        log, size = self.log, self.size
        head = self._at(0, len(MCAP_MAGIC))
        if head != MCAP_MAGIC:
            if 0 < len(head) < len(MCAP_MAGIC) and MCAP_MAGIC.startswith(head):
                raise LogFormatError(
                    f"{log.path}: cut off after {len(head)} octets, inside the MCAP magic: "
                    "nothing was recorded"
                )
            raise LogFormatError(f"{log.path}: not an MCAP file (bad magic)")
        self._summary_channels()
        p = len(MCAP_MAGIC)
        pending: tuple | None = None  # (chunk start, length, {channel: index array})
        while True:
            if p + 9 > size:
                if p < size:
                    log.truncated = True
                break
            op, length = _REC.unpack(self._at(p, 9))
            end = p + 9 + length
            if end > size:
                log.truncated = True
                break
            if op == 0x07 and pending is not None:  # message index of the pending chunk
                c = self.f.read(length)
                (cid,) = _U16(c, 0)
                (ln,) = _U32(c, 2)
                pending[2][cid] = np.frombuffer(c, dtype="<u8", count=ln // 8, offset=6).reshape(
                    -1, 2
                )
                p = end
                continue
            if pending is not None:
                self._chunk_done(*pending)
                pending = None
            if op != 0x06:  # any other record is taken after the chunks before it
                self._drain(0)
            if op == 0x06:
                pending = (p + 9, length, {})
            elif op == 0x0F:  # data end: the summary follows
                log.finalised = self._has_footer()
                break
            elif op in (0x05, 0x03, 0x04, 0x01, 0x0C, 0x09):
                c = self._at(p + 9, length)
                if op == 0x05:
                    cid, _, lt, _ = _MSG(c, 0)
                    self._add_one(cid, lt, c[22:])
                elif op == 0x03:
                    self._schema(c)
                elif op == 0x04:
                    self._channel(c)
                elif op == 0x01:
                    r = _read(mr.Header, c)
                    log.profile, log.library = r.profile, r.library
                elif op == 0x0C:
                    meta = _read(mr.Metadata, c)
                    log.metadata.setdefault(meta.name, {}).update(meta.metadata)
                else:
                    self._attachment(c)
            p = end
        if pending is not None:
            self._chunk_done(*pending)
        self._drain(0)
        for ch in log._chans.values():
            self._decode_pending(ch)

    def _has_footer(self) -> bool:
        if self.size < len(MCAP_MAGIC) + _FOOTER:
            return False
        tail = self._at(self.size - len(MCAP_MAGIC) - _FOOTER, len(MCAP_MAGIC) + _FOOTER)
        return tail.endswith(MCAP_MAGIC) and tail[0] == 0x02

    def _summary_channels(self) -> None:
        """The schemas and channels of a finalised file's summary section: with every channel
        known, a chunk without an asked topic need not be opened."""
        if not self._has_footer():
            return
        (start,) = _U64(self._at(self.size - len(MCAP_MAGIC) - _FOOTER + 9, 8))
        stop = self.size - len(MCAP_MAGIC) - _FOOTER
        if not len(MCAP_MAGIC) <= start <= stop:
            return
        summary = self._at(start, stop - start)
        p, n, seen, stats = 0, len(summary), False, None
        while p + 9 <= n:
            op, ln = _REC.unpack_from(summary, p)
            c = summary[p + 9 : p + 9 + ln]
            if op == 0x03:
                self._schema(c)
            elif op == 0x04:
                self._channel(c)
                seen = True
            elif op == 0x0B:
                stats = _read(mr.Statistics, c)
            p += 9 + ln
        self.all_known = seen and p == n
        if self.all_known and stats is not None:
            for cid, count in stats.channel_message_counts.items():
                if cid in self.log._chans:
                    self.log._chans[cid].expected = int(count)

    def _attachment(self, c: bytes) -> None:
        r = _read(mr.Attachment, c)  # the library skips the CRC: checked here
        (crc,) = _U32(c, len(c) - 4)
        if crc and crc != zlib.crc32(c[: len(c) - 4]):
            self.log.problems.append(f"attachment {r.name!r}: CRC mismatch")
        self.log.attachments.append(
            Attachment(r.name, r.media_type, bytes(r.data), r.log_time, r.create_time)
        )

    def _chunk_done(self, start: int, length: int, indexes: dict[int, np.ndarray]) -> None:
        chans = self.log._chans
        if (
            self.all_known
            and indexes
            and all(cid in chans for cid in indexes)
            and not any(chans[cid].wanted for cid, idx in indexes.items() if len(idx))
        ):
            for cid, idx in indexes.items():
                chans[cid].count += len(idx)
            self.log.chunks_skipped += 1
            return
        if self._pool is None:
            self._pool = ThreadPoolExecutor(1, thread_name_prefix="mcap-chunks")
        self._ahead.append((self._pool.submit(self._load, start, length), indexes, length))
        self._ahead_octets += length
        if len(self._ahead) >= _AHEAD + _MERGE or self._ahead_octets > _AHEAD_OCTETS:
            self._drain(_AHEAD)

    def _load(self, start: int, length: int) -> bytes | str:
        """A chunk's records, read (pread: the walk's file position is left alone), decompressed
        and CRC-checked, on the read-ahead thread."""
        if hasattr(os, "pread"):
            content = os.pread(self.f.fileno(), length, start)
        else:  # no pread (Windows): a handle of this thread's own
            if self._own is None:
                self._own = open(self.log.path, "rb")  # noqa: SIM115 (closed after the walk)
            self._own.seek(start)
            content = self._own.read(length)
        return chunk_records(content, self._decompressors)

    def _drain(self, keep: int) -> None:
        """Decode the chunks read ahead, oldest first, until ``keep`` are left in flight, holding
        at most ``_AHEAD_OCTETS`` compressed octets (a file of large chunks keeps fewer); up to
        ``_MERGE`` of them at a time, decoded as one (``_decode_merged``)."""
        while len(self._ahead) > keep or (self._ahead and self._ahead_octets > _AHEAD_OCTETS):
            group = []
            for _ in range(min(_MERGE, max(1, len(self._ahead) - keep))):
                fut, indexes, length = self._ahead.popleft()
                self._ahead_octets -= length
                group.append((fut.result(), indexes))
            self._decode_merged(group)

    def _decode_chunk(self, records: bytes | str, indexes: dict[int, np.ndarray]) -> None:
        if isinstance(records, str):
            self.log.problems.append(records)
            return
        self.log.chunks_read += 1
        if indexes and self._chunk_indexed(records, indexes):
            return
        self._chunk_sequential(records)

    def _decode_merged(self, group: list[tuple[bytes | str, dict[int, np.ndarray]]]) -> None:
        """Consecutive chunks decoded as one: their records joined and their message indexes
        shifted to match, so that the per-chunk work (a few dozen numpy calls) is done once for
        the group; each channel's messages keep their order. A group of one, one that is not all
        indexed chunks read whole, or one whose indexes do not account for its records, is
        decoded chunk by chunk (the same result)."""
        ok: list[tuple[bytes, dict[int, np.ndarray]]] = []
        for records, indexes in group:
            if not (isinstance(records, bytes) and indexes):
                break
            ok.append((records, indexes))
        if len(ok) > 1:
            base, merged = 0, dict[int, list[np.ndarray]]()
            for records, indexes in ok:
                for cid, idx in indexes.items():
                    merged.setdefault(cid, []).append(idx + np.array([0, base], np.uint64))
                base += len(records)
            joined = b"".join(records for records, _ in ok)
            if self._chunk_indexed(joined, {c: np.concatenate(p) for c, p in merged.items()}):
                self.log.chunks_read += len(ok)
                group = group[len(ok) :]
        for records, indexes in group:
            self._decode_chunk(records, indexes)

    def _take(self, ch: _Chan, buf: np.ndarray, starts, sizes, lts) -> None:
        """A batch of one channel's messages (data at ``starts`` in ``buf``) into its columns."""
        ch.count += len(starts)
        if not ch.wanted or ch.error:
            return
        lts = np.asarray(lts, dtype=np.uint64)
        codec = self.log._codec(ch)
        starts = np.asarray(starts, dtype=np.int64)
        sizes = np.asarray(sizes, dtype=np.int64)
        if self.sink is not None:
            self.sink(ch.topic, buf, starts, sizes, lts)
        if codec is None:
            ch.lts.append(lts)
            ch.var_data.extend(
                buf[a : a + n].tobytes()
                for a, n in zip(starts.tolist(), sizes.tolist(), strict=False)
            )
            return
        if codec.fixed and np.any(sizes != codec.size):
            ch.error = (
                f"{self.log.path}: {ch.topic}: messages of the wrong size for "
                f"{codec.topic.schema_name}"
            )
            return
        if codec.fixed:  # gathered and decoded at once, straight into the columns
            try:
                cols = decode_columns(codec, buf, starts, sizes, ch.fields, copy=False)
            except DecodeError as e:
                ch.error = f"{self.log.path}: {ch.topic}: {e}"
                return
            self._store(ch, lts, cols)
            return
        ch.pending.append(gather(buf, starts, sizes))
        ch.pending_sizes.append(sizes)
        ch.lts.append(lts)
        ch.pending_octets += int(sizes.sum())
        if ch.pending_octets >= _BATCH_OCTETS:
            self._decode_pending(ch)

    def _decode_pending(self, ch: _Chan) -> None:
        """The gathered messages of a channel decoded into its columns at once (few, large
        numpy operations instead of a few per chunk)."""
        if not ch.pending:
            return
        buf = np.concatenate(ch.pending) if len(ch.pending) > 1 else ch.pending[0]
        sizes = np.concatenate(ch.pending_sizes)
        lts = np.concatenate(ch.lts)
        ch.pending, ch.pending_sizes, ch.pending_octets, ch.lts = [], [], 0, []
        starts = np.cumsum(sizes) - sizes
        try:
            cols = decode_columns(self.log._codec(ch), buf, starts, sizes, ch.fields)
        except (DecodeError, UnicodeDecodeError) as e:
            ch.error = f"{self.log.path}: {ch.topic}: {e}"
            return
        self._store(ch, lts, cols)

    @staticmethod
    def _store(ch: _Chan, lts: np.ndarray, cols: dict[str, np.ndarray]) -> None:
        n = len(lts)
        if ch.expected >= 0 and ch.filled + n <= ch.expected and not ch.parts:
            # into columns of the final length (a finalised file's statistics): no second copy
            if ch.out_lt is None:
                ch.out_lt = np.empty(ch.expected, np.uint64)
                ch.out = {
                    k: np.empty(ch.expected, v.dtype.newbyteorder("=")) for k, v in cols.items()
                }
            a, b = ch.filled, ch.filled + n
            ch.out_lt[a:b] = lts
            for k, v in cols.items():
                ch.out[k][a:b] = v
            ch.filled = b
            return
        ch.parts.setdefault("", []).append(lts)
        for k, v in cols.items():
            ch.parts.setdefault(k, []).append(v.astype(v.dtype.newbyteorder("=")))  # a copy

    def _add_one(self, cid: int, lt: int, data: bytes) -> None:
        ch = self.log._chans.get(cid)
        if ch is None:
            self.log.problems.append(f"message on unknown channel {cid} skipped")
            return
        self._take(ch, np.frombuffer(data, np.uint8), [0], [len(data)], [lt])

    def _chunk_sequential(self, d: bytes) -> None:
        p, n = 0, len(d)
        unpack = _REC.unpack_from
        per: dict[int, tuple[list, list, list]] = {}
        while p + 9 <= n:
            op, ln = unpack(d, p)
            e = p + 9 + ln
            if e > n:
                self.log.problems.append("chunk ends inside a record")
                break
            if op == 0x05:
                cid, _, lt, _ = _MSG(d, p + 9)
                lst = per.get(cid)
                if lst is None:
                    lst = per[cid] = ([], [], [])
                lst[0].append(lt)
                lst[1].append(p + 31)
                lst[2].append(e - p - 31)
            elif op == 0x03:
                self._schema(d[p + 9 : e])
            elif op == 0x04:
                self._channel(d[p + 9 : e])
            p = e
        arr = np.frombuffer(d, dtype=np.uint8)
        for cid, (lts, starts, sizes) in per.items():
            ch = self.log._chans.get(cid)
            if ch is None:
                self.log.problems.append(f"{len(lts)} messages on unknown channel {cid} skipped")
                continue
            self._take(ch, arr, starts, sizes, lts)

    def _chunk_indexed(self, d: bytes, indexes: dict[int, np.ndarray]) -> bool:
        """Vectorised extraction using the chunk's message indexes; False if they do not
        account for every message record (then the chunk is scanned record by record)."""
        arr = np.frombuffer(d, dtype=np.uint8)
        n = len(d)
        all_offs = []
        plans = []
        for cid, idx in indexes.items():
            ch = self.log._chans.get(cid)
            if ch is None or len(idx) == 0:
                if ch is None and len(idx):
                    # the channel record may be in this chunk: scan it record by record
                    return False
                continue
            offs = idx[:, 1].astype(np.int64)
            if offs.min() < 0 or offs.max() + 31 > n:
                return False
            head = rows_at(arr, offs, 11)  # opcode, record length, channel id
            lens = head[:, 1:9].copy().view("<u8").reshape(-1).astype(np.int64)
            cids = head[:, 9:11].copy().view("<u2").reshape(-1)
            if (head[:, 0] != 0x05).any() or (cids != cid).any() or (offs + 9 + lens > n).any():
                return False
            all_offs.append(np.stack([offs, offs + 9 + lens], axis=1))
            plans.append((ch, idx, offs, lens))
        if not all_offs:
            return False
        spans = np.concatenate(all_offs)
        spans = spans[np.argsort(spans[:, 0], kind="stable")]
        # every byte not covered by an indexed message must be a non-message record
        gaps = []
        starts, ends = spans[:, 0], spans[:, 1]
        if np.any(starts[1:] < ends[:-1]):
            return False
        holes = np.nonzero(starts[1:] != ends[:-1])[0]
        edges = (
            [(0, int(starts[0]))]
            + [(int(ends[i]), int(starts[i + 1])) for i in holes]
            + [(int(ends[-1]), n)]
        )
        for a, b in edges:
            if a == b:
                continue
            p = a
            while p < b:
                if p + 9 > b:
                    return False
                op, ln = _REC.unpack_from(d, p)
                if op == 0x05 or p + 9 + ln > b:
                    return False
                gaps.append((op, p, p + 9 + ln))
                p += 9 + ln
        for op, a, b in gaps:
            if op == 0x03:
                self._schema(d[a + 9 : b])
            elif op == 0x04:
                self._channel(d[a + 9 : b])
        for ch, idx, offs, lens in plans:
            self._take(ch, arr, offs + 31, lens - 22, idx[:, 0])
        return True
