"""MCAP log writer: ros2msg + CDR messages in compressed chunks, crash-tolerant, deterministic.

    with LogWriter("run.mcap", metadata={"run": {...}}, attachments=[("profile.yaml",
                   "application/yaml", text.encode())]) as w:
        w.write("/pmsm/telemetry", t_s, {"speed_ref_rpm": 15.0, ...})
        w.write_many("/pmsm/telemetry", {"t_s": t, "speed_rpm": speed, ...})   # columns

- log_time = publish_time = round(t_s * 1e9) + the run's wall-clock start (``wall_start_s``, Unix
  time; 0 when not given): Foxglove shows real dates, ``t_s`` in every message stays device time.
  Without ``wall_start_s`` the same messages give the same file.
- The MCAP records are written here (not by ``mcap.writer``) so that a telemetry message costs one
  ``struct.pack``; the output is checked against the ``mcap`` reader and ``mcap_ros2`` decoder.
- A chunk is closed and written (then flushed to the OS) when it holds ``chunk_size`` octets or
  spans ``chunk_span_s`` of device time, so a killed process loses at most that much; the reader
  recovers such unfinalised files. ``close()`` is idempotent and may be called from ``finally``
  or a signal handler; SIGINT/SIGTERM are held back while a chunk is being written.
"""
from __future__ import annotations

import atexit
import contextlib
import os
import signal
import struct
import sys
import threading
import weakref
import zlib
from operator import itemgetter
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from pmsm_hil import __version__
from pmsm_hil.log.schemas import (LOG_FORMAT_VERSION, MESSAGE_ENCODING, PRIMITIVES, SCHEMA_ENCODING,
                                  TOPICS, Codec, TopicDef, codec_for, schema_hash)

__all__ = ["LogWriter", "MCAP_MAGIC", "available_compressions"]

MCAP_MAGIC = b"\x89MCAP0\r\n"
PROFILE = "ros2"
LIBRARY = f"pmsm-hil {__version__}"

OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE = 0x01, 0x02, 0x03, 0x04, 0x05
OP_CHUNK, OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_ATTACHMENT = 0x06, 0x07, 0x08, 0x09
OP_ATTACHMENT_INDEX, OP_STATISTICS, OP_METADATA, OP_METADATA_INDEX = 0x0A, 0x0B, 0x0C, 0x0D
OP_SUMMARY_OFFSET, OP_DATA_END = 0x0E, 0x0F

_REC = struct.Struct("<BQ")
_MSG_HDR = struct.Struct("<BQHIQQ")  # opcode, length, channel, sequence, log_time, publish_time
_MSG_HDR_SIZE = _MSG_HDR.size        # 31
_QQ = struct.Struct("<QQ").pack
_U32 = struct.Struct("<I").pack
_U64 = struct.Struct("<Q").pack
_CDR_HEADER_U32 = 0x100              # b"\x00\x01\x00\x00" packed as little-endian uint32
_LITTLE = sys.byteorder == "little"


def _s(text: str) -> bytes:
    b = text.encode("utf-8")
    return _U32(len(b)) + b


def _map(d: Mapping[str, str]) -> bytes:
    body = b"".join(_s(str(k)) + _s(str(v)) for k, v in d.items())
    return _U32(len(body)) + body


def _record(op: int, content: bytes) -> bytes:
    return _REC.pack(op, len(content)) + content


def available_compressions() -> list[str]:
    out = []
    import importlib.util

    if importlib.util.find_spec("zstandard") is not None:
        out.append("zstd")
    if importlib.util.find_spec("lz4") is not None:
        out.append("lz4")
    return out + [""]


def _compressor(name: str):
    if name == "zstd":
        import zstandard
        c = zstandard.ZstdCompressor(level=1)
        return c.compress
    if name == "lz4":
        import lz4.frame
        return lambda b: lz4.frame.compress(b)
    if name == "":
        return lambda b: b
    raise ValueError(f"compression {name!r}: choose one of {available_compressions()}")


_HELD_SIGNALS = {s for s in (getattr(signal, n, None) for n in ("SIGINT", "SIGTERM", "SIGHUP")) if s}


@contextlib.contextmanager
def _signals_held():
    """Hold SIGINT/SIGTERM/SIGHUP back while a chunk or the summary is written (POSIX)."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    try:
        old = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD_SIGNALS)
    except (OSError, ValueError):
        yield
        return
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


class _Channel:
    __slots__ = ("id", "schema_id", "topic", "codec", "seq", "count", "index", "getter", "n",
                 "pack", "reclen", "fixed", "names", "name_set", "rec_dtype")

    def __init__(self, cid: int, schema_id: int, topic: TopicDef):
        self.id = cid
        self.schema_id = schema_id
        self.topic = topic.topic
        self.codec: Codec = codec_for(topic)
        self.seq = 0
        self.count = 0
        self.index = bytearray()     # (log_time, offset) pairs of this channel in the open chunk
        self.names = self.codec.names[1:]          # without t_s
        self.name_set = frozenset(self.codec.names)
        self.n = len(self.names)
        self.getter = itemgetter(*self.names) if self.n > 1 else (lambda d, _k=self.names[0]: (d[_k],))
        self.fixed = self.codec.fixed
        if self.fixed:
            self.pack = struct.Struct("<BQHIQQI" + self.codec.body_format).pack
            self.reclen = 22 + self.codec.size    # record content length
            names = ["op", "len", "ch", "seq", "lt", "pt", "hdr"]
            formats = ["u1", "<u8", "<u2", "<u4", "<u8", "<u8", "<u4"]
            offsets = [0, 1, 9, 11, 15, 23, 31]
            dt = self.codec.dtype
            for nm in dt.names:
                formats.append(dt.fields[nm][0])
                offsets.append(_MSG_HDR_SIZE + dt.fields[nm][1])
                names.append("f_" + nm)
            self.rec_dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets,
                                       "itemsize": _MSG_HDR_SIZE + self.codec.size})
        else:
            self.pack = None
            self.reclen = None
            self.rec_dtype = None


class LogWriter:
    """Writes one MCAP log. See the module docstring; docs/log-format.md for the contract."""

    def __init__(self, path: str | os.PathLike, metadata: Mapping[str, Mapping[str, str]] | None = None,
                 attachments: Iterable[tuple[str, str, bytes]] = (), *, compression: str | None = None,
                 chunk_size: int = 1 << 20, chunk_span_s: float = 1.0, fsync: bool = False,
                 topics: Iterable[TopicDef] = (), wall_start_s: float | None = None):
        self.path = os.fspath(path)
        self._off_ns = int(round(wall_start_s * 1e9)) if wall_start_s else 0
        if compression is None:
            compression = available_compressions()[0]
        self._compression = compression
        self._compress = _compressor(compression)
        self._chunk_size = int(chunk_size)
        self._span_ns = int(round(chunk_span_s * 1e9))
        self._fsync = fsync
        self._topics: dict[str, TopicDef] = dict(TOPICS)
        for t in topics:
            self._topics[t.topic] = t
        self._lock = threading.RLock()
        self._closed = False
        self._closing = False
        self._f = open(self.path, "wb")
        self._pos = 0
        self._crc = 0                     # data section CRC
        self._schemas: dict[str, tuple[int, bytes]] = {}    # schema name -> (id, record)
        self._channels: dict[str, _Channel] = {}
        self._channel_records: list[bytes] = []
        self._chunk_indexes: list[bytes] = []
        self._attachment_indexes: list[bytes] = []
        self._metadata_indexes: list[bytes] = []
        self._n_metadata = 0
        self._n_attachments = 0
        self._n_chunks = 0
        self._msg_count = 0
        self._t_min: int | None = None
        self._t_max: int | None = None
        # open chunk
        self._parts: list[bytes] = []
        self._size = 0
        self._n = 0
        self._t0 = 0
        self._cmin = 0
        self._cmax = 0
        self._in_chunk: set[_Channel] = set()

        self._emit(MCAP_MAGIC + _record(OP_HEADER, _s(PROFILE) + _s(LIBRARY)))
        meta = {str(k): {str(a): str(b) for a, b in v.items()} for k, v in (metadata or {}).items()}
        meta.setdefault("log", {"format_version": str(LOG_FORMAT_VERSION), "schema_hash": schema_hash(),
                                "library": LIBRARY, "compression": compression or "none",
                                "log_time_offset_ns": str(self._off_ns)})
        for name, rec in meta.items():
            self.add_metadata(name, rec)
        for att in attachments:
            self.add_attachment(*att)
        self._f.flush()
        ref = weakref.ref(self)
        self._atexit = lambda: (w := ref()) is not None and w.close()
        atexit.register(self._atexit)

    # ------------------------------------------------------------------ file output
    def _emit(self, data: bytes) -> None:
        self._f.write(data)
        self._pos += len(data)
        self._crc = zlib.crc32(data, self._crc)

    # ------------------------------------------------------------------ records outside chunks
    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """A metadata record (name -> text map); written at once, outside the chunks."""
        with self._lock:
            self._check_open()
            rec = _record(OP_METADATA, _s(name) + _map({str(k): str(v) for k, v in data.items()}))
            self._metadata_indexes.append(_record(OP_METADATA_INDEX, _U64(self._pos) + _U64(len(rec)) + _s(name)))
            self._emit(rec)
            self._n_metadata += 1

    def add_attachment(self, name: str, media_type: str, data: bytes, log_time_s: float = 0.0,
                       create_time_s: float = 0.0) -> None:
        """An attachment (a file's bytes); written at once, outside the chunks."""
        with self._lock:
            self._check_open()
            data = bytes(data)
            lt, ct = int(round(log_time_s * 1e9)), int(round(create_time_s * 1e9))
            body = _U64(lt) + _U64(ct) + _s(name) + _s(media_type) + _U64(len(data)) + data
            rec = _record(OP_ATTACHMENT, body + _U32(zlib.crc32(body)))
            self._attachment_indexes.append(_record(
                OP_ATTACHMENT_INDEX, _U64(self._pos) + _U64(len(rec)) + _U64(lt) + _U64(ct) + _U64(len(data))
                + _s(name) + _s(media_type)))
            self._emit(rec)
            self._n_attachments += 1

    def _open_channel(self, topic: str) -> _Channel:
        td = self._topics.get(topic)
        if td is None:
            raise KeyError(f"unknown topic {topic!r}: known are {', '.join(self._topics)} "
                           f"(pass a TopicDef in topics= to add one)")
        self._check_open()
        sch = self._schemas.get(td.schema_name)
        if sch is None:
            sid = len(self._schemas) + 1
            text = td.msgdef.encode("utf-8")
            rec = _record(OP_SCHEMA, struct.pack("<H", sid) + _s(td.schema_name) + _s(SCHEMA_ENCODING)
                          + _U32(len(text)) + text)
            self._schemas[td.schema_name] = (sid, rec)
            self._emit(rec)
        else:
            sid = sch[0]
        cid = len(self._channels) + 1
        rec = _record(OP_CHANNEL, struct.pack("<HH", cid, sid) + _s(topic) + _s(MESSAGE_ENCODING) + _map({}))
        self._emit(rec)
        self._channel_records.append(rec)
        ch = _Channel(cid, sid, td)
        self._channels[topic] = ch
        return ch

    def _check_open(self) -> None:
        if self._closed or self._closing:
            raise ValueError(f"{self.path}: the log writer is closed")

    # ------------------------------------------------------------------ messages
    def write(self, topic: str, t_s: float, fields: Mapping[str, Any]) -> None:
        """One message at device time ``t_s``. ``fields`` maps field names to values; missing
        fields are written as NaN / 0 / "" / false, unknown names raise KeyError."""
        ch = self._channels.get(topic)
        if ch is None:
            with self._lock:
                ch = self._channels.get(topic) or self._open_channel(topic)
        if self._closed:
            raise ValueError(f"{self.path}: the log writer is closed")
        try:
            lt = round(t_s * 1e9)
            if lt < 0:
                raise ValueError
            lt += self._off_ns
        except (ValueError, OverflowError, TypeError):
            raise ValueError(f"{topic}: t_s = {t_s!r} is not a device time (finite, >= 0 s)") from None
        rec = None
        if ch.fixed:
            nf = len(fields)
            if nf == ch.n or (nf == ch.n + 1 and "t_s" in fields):
                try:
                    rec = ch.pack(5, ch.reclen, ch.id, ch.seq, lt, lt, 0x100, t_s, *ch.getter(fields))
                except (KeyError, struct.error, TypeError):
                    rec = None
            if rec is None:
                vals = self._values(ch, t_s, fields)
                try:
                    rec = ch.pack(5, ch.reclen, ch.id, ch.seq, lt, lt, 0x100, *vals)
                except struct.error as e:
                    raise self._value_error(ch, vals, e) from None
        else:
            vals = self._values(ch, t_s, fields)
            try:
                data = ch.codec.encode(vals)
                rec = _MSG_HDR.pack(5, 22 + len(data), ch.id, ch.seq, lt, lt) + data
            except (struct.error, TypeError) as e:
                raise self._value_error(ch, vals, e) from None
        ch.seq = (ch.seq + 1) & 0xFFFFFFFF
        # --- append to the open chunk (data first, then the index: an interruption in between
        # costs at most this message's index entry)
        with self._lock:
            if self._n:
                if lt - self._t0 >= self._span_ns:
                    self._flush_chunk()
            if not self._n:
                self._t0 = self._cmin = self._cmax = lt
            off = self._size
            self._parts.append(rec)
            ch.index += _QQ(lt, off)
            self._size = off + len(rec)
            self._n += 1
            ch.count += 1
            self._in_chunk.add(ch)
            if lt < self._cmin:
                self._cmin = lt
            elif lt > self._cmax:
                self._cmax = lt
            if self._size >= self._chunk_size:
                self._flush_chunk()

    @staticmethod
    def _values(ch: _Channel, t_s: float, fields: Mapping[str, Any]) -> list:
        unknown = [k for k in fields if k not in ch.name_set]
        if unknown:
            raise KeyError(f"{ch.topic}: unknown field(s) {', '.join(map(repr, unknown))}; "
                           f"fields are {', '.join(ch.codec.names)}")
        return [t_s] + [fields.get(n, d) for n, d in zip(ch.names, ch.codec.defaults[1:])]

    @staticmethod
    def _value_error(ch: _Channel, vals: Sequence[Any], e: Exception) -> ValueError:
        bad = []
        for f, v in zip(ch.codec.fields, vals):
            try:
                if f.type == "string":
                    ok = isinstance(v, str)
                else:
                    struct.pack("<" + PRIMITIVES[f.type][0], v)
                    ok = True
            except (struct.error, TypeError, OverflowError):
                ok = False
            if not ok:
                bad.append(f"{f.name} = {v!r} (not a {f.type})")
        return ValueError(f"{ch.topic}: cannot encode {'; '.join(bad) or list(vals)}: {e}")

    def write_many(self, topic: str, rows: Any) -> int:
        """Many messages at once; returns the count. ``rows``: a mapping of columns (``t_s`` and
        field arrays of one length), a numpy structured array, or an iterable of mappings.
        Produces exactly the bytes that the same ``write`` calls would."""
        ch = self._channels.get(topic)
        if ch is None:
            with self._lock:
                ch = self._channels.get(topic) or self._open_channel(topic)
        if isinstance(rows, np.ndarray) and rows.dtype.names:
            cols = {n: rows[n] for n in rows.dtype.names}
        elif isinstance(rows, Mapping):
            cols = dict(rows)
        else:
            n = 0
            for r in rows:
                r = dict(r)
                t = r.pop("t_s")
                self.write(topic, t, r)
                n += 1
            return n
        if "t_s" not in cols:
            raise KeyError(f"{topic}: write_many needs a t_s column")
        unknown = [k for k in cols if k not in ch.name_set]
        if unknown:
            raise KeyError(f"{topic}: unknown field(s) {', '.join(map(repr, unknown))}")
        t = np.asarray(cols["t_s"], dtype=np.float64).reshape(-1)
        count = len(t)
        if count == 0:
            return 0
        if not ch.fixed:
            present = [(nm, list(np.asarray(cols[nm], dtype=object).reshape(-1))) for nm in ch.names
                       if nm in cols]
            for nm, c in present:
                if len(c) != count:
                    raise ValueError(f"{topic}.{nm}: {len(c)} values for {count} rows")
            for i in range(count):
                self.write(topic, float(t[i]), {nm: (c[i].item() if hasattr(c[i], "item") else c[i])
                                                for nm, c in present})
            return count
        lt = np.rint(t * 1e9).astype(np.uint64) + np.uint64(self._off_ns)
        if np.any(t < 0) or not np.all(np.isfinite(t)):
            raise ValueError(f"{topic}: t_s must be finite and >= 0")
        recs = np.zeros(count, dtype=ch.rec_dtype)
        recs["op"] = 5
        recs["len"] = ch.reclen
        recs["ch"] = ch.id
        recs["seq"] = (np.arange(count, dtype=np.uint64) + ch.seq) & 0xFFFFFFFF
        recs["lt"] = lt
        recs["pt"] = lt
        recs["hdr"] = 0x100
        recs["f_t_s"] = t
        for nm, f in zip(ch.names, ch.codec.fields[1:]):
            c = cols.get(nm)
            if c is None:
                recs["f_" + nm] = f.default
            else:
                c = np.asarray(c)
                if c.shape != (count,) and c.ndim != 0:
                    raise ValueError(f"{topic}.{nm}: {c.shape[0] if c.ndim else 1} values for {count} rows")
                if f.type == "bool":
                    c = c.astype(bool)
                elif f.type not in ("float32", "float64"):
                    info = np.iinfo(recs.dtype.fields["f_" + nm][0])
                    if c.size and (np.any(c < info.min) or np.any(c > info.max)):
                        raise ValueError(f"{topic}.{nm}: values outside the {f.type} range")
                recs["f_" + nm] = c
        ch.seq = int((ch.seq + count) & 0xFFFFFFFF)
        raw = recs.tobytes()
        rsize = ch.rec_dtype.itemsize
        lt_list = lt
        i = 0
        with self._lock:
            self._check_open()
            while i < count:
                if self._n and int(lt_list[i]) - self._t0 >= self._span_ns:
                    self._flush_chunk()
                if not self._n:
                    self._t0 = int(lt_list[i])
                    self._cmin = self._cmax = self._t0
                room = max(1, -(-(self._chunk_size - self._size) // rsize))  # messages until full
                k = min(room, count - i)
                window = lt_list[i:i + k].astype(np.int64)
                late = np.nonzero(window - self._t0 >= self._span_ns)[0]
                if len(late):
                    k = int(late[0])     # > 0: element i passed the check above
                seg = slice(i, i + k)
                offs = self._size + np.arange(k, dtype=np.uint64) * rsize
                pairs = np.empty((k, 2), dtype="<u8")
                pairs[:, 0] = lt_list[seg]
                pairs[:, 1] = offs
                self._parts.append(raw[i * rsize:(i + k) * rsize])
                ch.index += pairs.tobytes()
                self._size += k * rsize
                self._n += k
                ch.count += k
                self._in_chunk.add(ch)
                lo, hi = int(window[:k].min()), int(window[:k].max())
                if lo < self._cmin:
                    self._cmin = lo
                if hi > self._cmax:
                    self._cmax = hi
                i += k
                if self._size >= self._chunk_size or len(late):
                    self._flush_chunk()
        return count

    # ------------------------------------------------------------------ chunks
    def flush(self) -> None:
        """Close the open chunk and write it out now."""
        with self._lock:
            if not self._closed:
                self._flush_chunk()

    def _flush_chunk(self) -> None:
        if not self._n or self._f.closed:
            return
        with _signals_held():
            records = b"".join(self._parts)
            usize = len(records)
            comp = self._compress(records)
            start = self._pos
            chunk = _record(OP_CHUNK, struct.pack("<QQQI", self._cmin, self._cmax, usize, zlib.crc32(records))
                            + _s(self._compression) + _U64(len(comp)) + comp)
            out = [chunk]
            pos = start + len(chunk)
            offsets = []
            for ch in sorted(self._in_chunk, key=lambda c: c.id):
                idx = bytes(ch.index)
                rec = _record(OP_MESSAGE_INDEX, struct.pack("<H", ch.id) + _U32(len(idx)) + idx)
                offsets.append(struct.pack("<HQ", ch.id, pos))
                pos += len(rec)
                out.append(rec)
                ch.index = bytearray()
            self._emit(b"".join(out))
            self._f.flush()
            if self._fsync:
                os.fsync(self._f.fileno())
            offs = b"".join(offsets)
            self._chunk_indexes.append(_record(
                OP_CHUNK_INDEX, struct.pack("<QQQQ", self._cmin, self._cmax, start, len(chunk))
                + _U32(len(offs)) + offs + _U64(pos - start - len(chunk)) + _s(self._compression)
                + _U64(len(comp)) + _U64(usize)))
            self._n_chunks += 1
            self._msg_count += self._n
            self._t_min = self._cmin if self._t_min is None else min(self._t_min, self._cmin)
            self._t_max = self._cmax if self._t_max is None else max(self._t_max, self._cmax)
            self._parts = []
            self._size = 0
            self._n = 0
            self._in_chunk = set()

    # ------------------------------------------------------------------ closing
    def close(self) -> None:
        """Write the last chunk, the summary and the footer. Safe to call more than once, from
        ``finally`` or from a signal handler (a re-entrant call returns at once)."""
        if self._closed or self._closing:
            return
        self._closing = True
        try:
            with self._lock, _signals_held():
                self._flush_chunk()
                self._write_summary()
        finally:
            self._closed = True
            try:
                self._f.close()
            finally:
                atexit.unregister(self._atexit)

    def _write_summary(self) -> None:
        self._emit(_record(OP_DATA_END, _U32(self._crc)))
        summary_start = self._pos
        groups: list[tuple[int, list[bytes]]] = [
            (OP_SCHEMA, [r for _, r in self._schemas.values()]),
            (OP_CHANNEL, self._channel_records),
            (OP_STATISTICS, [self._statistics()]),
            (OP_CHUNK_INDEX, self._chunk_indexes),
            (OP_ATTACHMENT_INDEX, self._attachment_indexes),
            (OP_METADATA_INDEX, self._metadata_indexes),
        ]
        body = []
        offsets = []
        pos = summary_start
        for op, recs in groups:
            if not recs:
                continue
            data = b"".join(recs)
            offsets.append(_record(OP_SUMMARY_OFFSET, struct.pack("<BQQ", op, pos, len(data))))
            body.append(data)
            pos += len(data)
        summary = b"".join(body)
        summary_offset_start = pos
        tail = b"".join(offsets)
        footer_head = struct.pack("<BQQQ", OP_FOOTER, 20, summary_start if summary else 0, summary_offset_start)
        crc = zlib.crc32(footer_head, zlib.crc32(tail, zlib.crc32(summary)))
        self._f.write(summary + tail + footer_head + _U32(crc) + MCAP_MAGIC)
        self._f.flush()
        if self._fsync:
            os.fsync(self._f.fileno())

    def _statistics(self) -> bytes:
        counts = b"".join(struct.pack("<HQ", ch.id, ch.count) for ch in self._channels.values())
        return _record(OP_STATISTICS, struct.pack(
            "<QHIIIIQQ", self._msg_count, len(self._schemas), len(self._channels), self._n_attachments,
            self._n_metadata, self._n_chunks, self._t_min or 0, self._t_max or 0) + _U32(len(counts)) + counts)

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def message_count(self) -> int:
        """Messages written so far (including the open chunk)."""
        return self._msg_count + self._n

    def __enter__(self) -> "LogWriter":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
