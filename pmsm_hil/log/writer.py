"""MCAP log writer: ros2msg + CDR messages in compressed chunks, crash-tolerant, deterministic.

    with LogWriter("run.mcap", metadata={"run": {...}}, attachments=[("profile.yaml",
                   "application/yaml", text.encode())]) as w:
        w.write("/pmsm/telemetry", t_s, {"speed_ref_rpm": 15.0, ...})
        w.write_many("/pmsm/telemetry", {"t_s": t, "speed_rpm": speed, ...})   # columns

- log_time = publish_time = round(t_s * 1e9) + the run's wall-clock start (``wall_start_s``, Unix
  time; 0 when not given): Foxglove shows real dates, ``t_s`` in every message stays device time.
  Without ``wall_start_s`` the same messages give the same file.
- The MCAP records (chunks, indexes, summary) are laid out as the ``mcap`` library's ``Writer``
  lays them out, encoded by its record classes, a message record by one ``struct.pack``
  (pmsm_hil.log.mcap_file); the CDR payloads by the project's codecs (pmsm_hil.log.schemas: one
  ``struct.pack`` per message, byte-identical to ``mcap_ros2``'s encoder).
  benchmarks/log_writer.py measures the rate.
- A chunk is closed and written (then flushed to the OS) when it holds ``chunk_size`` octets or
  spans ``chunk_span_s`` of device time, and, with ``flush_wall_s``, once it has been open that long
  in wall time (checked at each message and by ``flush_if_due()``): a killed process loses at most
  the open chunk, i.e. the messages of the last ``flush_wall_s`` of wall time (and never more than
  ``chunk_span_s`` of device time); the reader recovers such unfinalised files. With ``journal``
  the open chunk's messages are also appended to ``LOG.journal`` and written to the OS by
  ``flush_batch()`` (the run's Recorder calls it at the end of each receive batch): a killed
  process then loses nothing it had received (pmsm_hil.log.journal; ``pmsm-hil log recover``
  merges the journal). ``close()`` is idempotent and may be called from ``finally`` or a signal handler;
  SIGINT/SIGTERM are held back while a chunk is being written.
"""

from __future__ import annotations

import atexit
import os
import struct
import threading
import time
import weakref
from bisect import bisect_left
from collections.abc import Callable, Iterable, Mapping, Sequence
from operator import itemgetter
from typing import Any, NamedTuple

import numpy as np

from pmsm_hil import __version__
from pmsm_hil.log.blocks import MessageBlock, cdr_from_columns, log_times
from pmsm_hil.log.journal import Journal
from pmsm_hil.log.mcap_file import MAGIC, McapFile
from pmsm_hil.log.schemas import (
    LOG_FORMAT_VERSION,
    MESSAGE_ENCODING,
    PRIMITIVES,
    SCHEMA_ENCODING,
    TOPICS,
    Codec,
    TopicDef,
    codec_for,
    schema_hash,
)
from pmsm_hil.log.write_support import (
    LogWriteError,
    available_compressions,
    check_compression,
    signals_held,
)

__all__ = ["MCAP_MAGIC", "FixedLayout", "LogWriteError", "LogWriter", "available_compressions"]


MCAP_MAGIC = MAGIC
PROFILE = "ros2"
LIBRARY = f"pmsm-hil {__version__}"


class FixedLayout(NamedTuple):
    names: tuple[str, ...]  # t_s first; not the strings of a topic with strings
    dtype: np.dtype  # the CDR data: encapsulation header, then the fields at their offsets
    template: bytes | None = None  # with strings: the data's header and strings in place


class _Channel:
    __slots__ = (
        "codec",
        "count",
        "dtype",
        "fixed",
        "getter",
        "id",
        "layouts",
        "n",
        "name_set",
        "names",
        "pack",
        "seq",
        "topic",
    )

    def __init__(self, cid: int, topic: TopicDef):
        self.id = cid
        self.topic = topic.topic
        self.codec: Codec = codec_for(topic)
        self.seq = 0
        self.count = 0
        self.names = self.codec.names[1:]  # without t_s
        self.name_set = frozenset(self.codec.names)
        self.n = len(self.names)
        self.getter = (
            itemgetter(*self.names) if self.n > 1 else (lambda d, _k=self.names[0]: (d[_k],))
        )
        self.fixed = self.codec.fixed
        # fixed layout: the whole CDR data (encapsulation header as a uint32, then the fields);
        # the codec has a body format and a dtype exactly when it is fixed
        body = self.codec.body_format
        self.pack: Callable[..., bytes] | None = (
            struct.Struct("<I" + body).pack if self.fixed and body is not None else None
        )
        self.dtype: np.dtype | None = self.codec.dtype if self.fixed else None
        self.layouts: set[np.dtype] = set()  # with strings: the layouts given out (fixed_layout)


class LogWriter:
    """Writes one MCAP log. See the module docstring; docs/log-format.md for the contract."""

    def __init__(
        self,
        path: str | os.PathLike,
        metadata: Mapping[str, Mapping[str, str]] | None = None,
        attachments: Iterable[tuple[str, str, bytes]] = (),
        *,
        compression: str | None = None,
        chunk_size: int = 1 << 20,
        chunk_span_s: float = 1.0,
        fsync: bool = False,
        topics: Iterable[TopicDef] = (),
        wall_start_s: float | None = None,
        flush_wall_s: float | None = None,
        journal: bool = False,
    ):
        self.path = os.fspath(path)
        self._off_ns = round(wall_start_s * 1e9) if wall_start_s else 0
        if compression is None:
            compression = available_compressions()[0]
        check_compression(compression)
        self._chunk_size = int(chunk_size)
        self._span_ns = round(chunk_span_s * 1e9)
        self._flush_wall_s = float(flush_wall_s) if flush_wall_s else 0.0
        self._wall0 = 0.0  # wall time (monotonic) of the open chunk's first message
        self._fsync = fsync
        self._topics: dict[str, TopicDef] = dict(TOPICS)
        for t in topics:
            self._topics[t.topic] = t
        self._lock = threading.RLock()
        self._closed = False
        self._closing = False
        self._failed: LogWriteError | None = None
        self._last_lt = 0  # log time of the last message added
        self._disk_lt: int | None = None  # ... of the last message in a chunk on disk
        self._f = open(self.path, "wb")  # noqa: SIM115  (held by the writer until close())
        self._journal = Journal(self.path, PROFILE, LIBRARY) if journal else None
        # the records; its open chunk's octets (``size``) and messages (``n``)
        self._w = McapFile(self._f, compression, PROFILE, LIBRARY)
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, _Channel] = {}
        self._msg_count = 0  # messages in the chunks written
        self._t0 = 0  # log time of the open chunk's first message
        meta = {str(k): {str(a): str(b) for a, b in v.items()} for k, v in (metadata or {}).items()}
        log_meta = {
            "format_version": str(LOG_FORMAT_VERSION),
            "schema_hash": schema_hash(),
            "library": LIBRARY,
            "compression": compression or "none",
            "log_time_offset_ns": str(self._off_ns),
        }
        if self._flush_wall_s:  # the loss bound of a killed writer, for `pmsm-hil log recover`
            log_meta["chunk_span_s"] = repr(float(chunk_span_s))
            log_meta["flush_wall_s"] = repr(self._flush_wall_s)
        if journal:  # the open chunk's messages also go to LOG.journal (pmsm_hil.log.journal)
            log_meta["journal"] = "true"
        meta.setdefault("log", log_meta)
        for name, rec in meta.items():
            self.add_metadata(name, rec)
        for att in attachments:
            self.add_attachment(*att)
        self._f.flush()
        ref = weakref.ref(self)

        def close_at_exit() -> None:
            w = ref()
            if w is not None:
                w.close()

        self._atexit = close_at_exit
        atexit.register(self._atexit)

    # ------------------------------------------------------------------ records outside chunks
    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """A metadata record (name -> text map); written at once, outside the chunks."""
        with self._lock:
            self._check_open()
            self._w.add_metadata(name, {str(k): str(v) for k, v in data.items()})

    def add_attachment(
        self,
        name: str,
        media_type: str,
        data: bytes,
        log_time_s: float = 0.0,
        create_time_s: float = 0.0,
    ) -> None:
        """An attachment (a file's bytes); written at once, outside the chunks."""
        with self._lock:
            self._check_open()
            self._w.add_attachment(
                create_time=round(create_time_s * 1e9),
                log_time=round(log_time_s * 1e9),
                name=name,
                media_type=media_type,
                data=bytes(data),
            )

    def _open_channel(self, topic: str) -> _Channel:
        td = self._topics.get(topic)
        if td is None:
            raise KeyError(
                f"unknown topic {topic!r}: known are {', '.join(self._topics)} "
                f"(pass a TopicDef in topics= to add one)"
            )
        self._check_open()
        sid = self._schemas.get(td.schema_name)
        if sid is None:
            schema = self._w.register_schema(
                td.schema_name, SCHEMA_ENCODING, td.msgdef.encode("utf-8")
            )
            sid = self._schemas[td.schema_name] = schema.id
            if self._journal is not None:
                self._journal.define(schema)
        channel = self._w.register_channel(topic, MESSAGE_ENCODING, sid)
        if self._journal is not None:
            self._journal.define(channel)
        ch = _Channel(channel.id, td)
        self._channels[topic] = ch
        return ch

    def _check_open(self) -> None:
        if self._failed is not None:
            raise self._failed
        if self._closed or self._closing:
            raise ValueError(f"{self.path}: the log writer is closed")

    def _fail(self, err: OSError) -> LogWriteError:
        """An I/O error: the writer stops writing for good (see LogWriteError)."""
        if self._failed is None:
            try:
                octets = os.fstat(self._f.fileno()).st_size
            except (OSError, ValueError):
                octets = 0
            t = None if self._disk_lt is None else (self._disk_lt - self._off_ns) / 1e9
            self._failed = LogWriteError(self.path, err, octets, t)
        return self._failed

    @property
    def failed(self) -> LogWriteError | None:
        """The write error that stopped this writer, or None."""
        return self._failed

    # ------------------------------------------------------------------ messages
    def write(self, topic: str, t_s: float, fields: Mapping[str, Any]) -> None:
        """One message at device time ``t_s``. ``fields`` maps field names to values; missing
        fields are written as NaN / 0 / "" / false, unknown names raise KeyError."""
        ch = self._channels.get(topic)
        if ch is None:
            with self._lock:
                ch = self._channels.get(topic) or self._open_channel(topic)
        if self._closed:
            self._check_open()  # LogWriteError after a write error, else ValueError
        try:
            lt = round(t_s * 1e9)
            if lt < 0:
                raise ValueError
            lt += self._off_ns
        except (ValueError, OverflowError, TypeError):
            raise ValueError(
                f"{topic}: t_s = {t_s!r} is not a device time (finite, >= 0 s)"
            ) from None
        data: bytes | None = None
        pack = ch.pack  # set exactly when the layout is fixed
        if pack is not None:
            nf = len(fields)
            if nf == ch.n or (nf == ch.n + 1 and "t_s" in fields):
                try:
                    data = pack(0x100, t_s, *ch.getter(fields))
                except (KeyError, struct.error, TypeError):
                    data = None
            if data is None:
                vals = self._values(ch, t_s, fields)
                try:
                    data = pack(0x100, *vals)
                except struct.error as e:
                    raise self._value_error(ch, vals, e) from None
        else:
            vals = self._values(ch, t_s, fields)
            try:
                data = ch.codec.encode(vals)
            except (struct.error, TypeError) as e:
                raise self._value_error(ch, vals, e) from None
        with self._lock:
            self._check_open()
            self._add(ch, lt, data)

    def _add(self, ch: _Channel, lt: int, data: bytes) -> None:
        """One message into the open chunk; the chunk is closed before it when it spans
        chunk_span_s, after it when it holds chunk_size octets. Called with the lock held."""
        w = self._w
        if w.n and (lt - self._t0 >= self._span_ns or self._wall_due()):
            self._flush_chunk()
        if not w.n:
            self._t0 = lt
            if self._flush_wall_s:
                self._wall0 = time.monotonic()
        rec = w.add_message(ch.id, ch.seq, lt, data)
        if self._journal is not None:
            self._journal.add_record(rec)
        self._last_lt = lt
        ch.seq = (ch.seq + 1) & 0xFFFFFFFF
        ch.count += 1
        if w.size >= self._chunk_size:
            self._flush_chunk()

    @staticmethod
    def _values(ch: _Channel, t_s: float, fields: Mapping[str, Any]) -> list:
        unknown = [k for k in fields if k not in ch.name_set]
        if unknown:
            raise KeyError(
                f"{ch.topic}: unknown field(s) {', '.join(map(repr, unknown))}; "
                f"fields are {', '.join(ch.codec.names)}"
            )
        return [t_s] + [
            fields.get(n, d) for n, d in zip(ch.names, ch.codec.defaults[1:], strict=False)
        ]

    @staticmethod
    def _value_error(ch: _Channel, vals: Sequence[Any], e: Exception) -> ValueError:
        bad = []
        for f, v in zip(ch.codec.fields, vals, strict=False):
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

    def fixed_layout(
        self, topic: str, strings: Mapping[str, str] | None = None
    ) -> FixedLayout | None:
        """A topic of fixed layout: its field names (``t_s`` first) and the numpy dtype of its
        whole CDR data (for ``message_block``). A topic with strings has one when each string's
        value is given (``strings``: field -> text): its other fields' names and layout, and the
        data's template with the strings in place; None without them."""
        ch = self._channels.get(topic)
        if ch is None:
            with self._lock:
                ch = self._channels.get(topic) or self._open_channel(topic)
        if ch.dtype is not None:
            return FixedLayout(tuple(ch.codec.names), ch.dtype)
        if not strings:
            return None
        dtype, template = ch.codec.layout(strings)
        ch.layouts.add(dtype)
        fields = set(dtype.names or ())
        return FixedLayout(tuple(n for n in ch.codec.names if n in fields), dtype, template)

    def message_block(self, topic: str, t_s: Any, data: np.ndarray) -> MessageBlock:
        """Messages of a fixed-layout topic made at once, to be written in order by
        ``write_block`` (between other messages if need be): ``t_s`` their device times, ``data``
        their CDR data (``Codec.dtype`` of the topic: encapsulation header and fields; for a
        topic with strings, a layout ``fixed_layout`` gave, filled from its template)."""
        ch = self._channels.get(topic)
        if ch is None:
            with self._lock:
                ch = self._channels.get(topic) or self._open_channel(topic)
        size = data.dtype.itemsize * (data.shape[1] if data.ndim > 1 else 1)
        fixed = ch.dtype is not None and size == ch.dtype.itemsize
        if not (fixed or data.dtype in ch.layouts):
            raise ValueError(f"{topic}: data of {data.dtype} is not the topic's fixed layout")
        return MessageBlock(topic, ch.id, ch.seq, log_times(topic, t_s, self._off_ns), data)

    def write_block(self, block: MessageBlock, stop: int | None = None) -> None:
        """The block's messages from ``block.pos`` up to ``stop`` (all by default), in order: the
        records ``write`` would make, the chunks closed where it would close them (the wall-time
        bound checked once per chunk's part instead of per message)."""
        self.write_runs(((block, len(block) if stop is None else stop),))

    def write_runs(self, runs: Iterable[tuple[MessageBlock, int]]) -> None:
        """``write_block(block, stop)`` for each run, the lock taken once (paper-a: 13 000 runs)."""
        with self._lock:
            if self._failed is not None or self._closed or self._closing:
                self._check_open()
            w, span, limit = self._w, self._span_ns, self._chunk_size
            pending = self._journal.pending if self._journal is not None else None
            for block, stop in runs:
                ch = self._channels[block.topic]
                if (block.seq0 + block.pos) & 0xFFFFFFFF != ch.seq:  # others came between
                    block.renumber(ch.seq)
                i, times, raw, size = block.pos, block.times, block.raw, block.size
                while i < stop:
                    lt = times[i]
                    if w.n and (lt - self._t0 >= span or self._wall_due()):
                        self._flush_chunk()
                    if not w.n:
                        self._t0, self._wall0 = lt, time.monotonic()
                    j = min(stop, i + max(1, -(-(limit - w.size) // size)))
                    if not block.increasing or times[j - 1] - self._t0 >= span:
                        j = self._span_end(block, i, j)  # the chunk's span ends within the run
                    part = raw[i * size : j * size]
                    w.add_records(ch.id, times[i:j], part, size)
                    if pending is not None:
                        pending.append(part)
                    self._last_lt = times[j - 1]
                    ch.seq = (ch.seq + (j - i)) & 0xFFFFFFFF
                    ch.count += j - i
                    if w.size >= limit:
                        self._flush_chunk()
                    i = j
                block.pos = max(block.pos, stop)

    def _span_end(self, block: MessageBlock, i: int, j: int) -> int:
        """The first of the block's messages i+1 .. j-1 whose log time reaches the open chunk's
        span (``write`` closes the chunk before it), or j."""
        end = self._t0 + self._span_ns
        if block.increasing:
            return j if block.times[j - 1] < end else bisect_left(block.times, end, i + 1, j)
        late = np.flatnonzero(block.log_times[i + 1 : j] >= end)
        return i + 1 + int(late[0]) if late.size else j

    def _wall_due(self) -> bool:
        return bool(self._flush_wall_s) and time.monotonic() - self._wall0 >= self._flush_wall_s

    def write_encoded(self, topic: str, log_time: int, data: bytes) -> None:
        """One message as it is in an MCAP file: its log time (ns, this writer's offset
        included) and its CDR data (e.g. from a journal, ``rewrite_log``)."""
        self.write_encoded_many(topic, (log_time,), (data,))

    def write_encoded_many(
        self, topic: str, log_times: Iterable[int], datas: Iterable[bytes | memoryview]
    ) -> None:
        """Messages of one topic as they are in an MCAP file (``write_encoded`` each), under one
        taking of the lock: a log rewritten chunk by chunk (``rewrite_log``)."""
        ch = self._channels.get(topic)
        with self._lock:
            ch = ch or self._open_channel(topic)
            self._check_open()
            add = self._add
            for lt, data in zip(log_times, datas, strict=True):
                add(ch, int(lt), bytes(data))

    def write_many(self, topic: str, rows: Any) -> int:
        """Many messages at once; returns the count. ``rows``: a mapping of columns (``t_s`` and
        field arrays of one length), a numpy structured array, or an iterable of mappings.
        Produces exactly the bytes that the same ``write`` calls would."""
        ch = self._channels.get(topic)
        if ch is None:
            with self._lock:
                ch = self._channels.get(topic) or self._open_channel(topic)
        cols: dict[str, Any]
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
        dtype = ch.dtype  # set exactly when the layout is fixed
        if dtype is None:
            present = [
                (nm, list(np.asarray(cols[nm], dtype=object).reshape(-1)))
                for nm in ch.names
                if nm in cols
            ]
            for nm, c in present:
                if len(c) != count:
                    raise ValueError(f"{topic}.{nm}: {len(c)} values for {count} rows")
            for i in range(count):
                self.write(
                    topic,
                    float(t[i]),
                    {nm: (c[i].item() if hasattr(c[i], "item") else c[i]) for nm, c in present},
                )
            return count
        recs = cdr_from_columns(topic, ch.codec, cols, count)
        self.write_block(self.message_block(topic, t, recs))
        return count

    # ------------------------------------------------------------------ chunks
    def flush(self) -> None:
        """Close the open chunk and write it out now."""
        with self._lock:
            if not self._closed:
                self._flush_chunk()

    def flush_batch(self) -> None:
        """The end of a receive batch: with ``journal``, the messages added since the last call
        go to the OS (appended to the journal); without, nothing (the chunks go as they fill)."""
        if self._journal is None:
            return
        with self._lock:
            if self._closed or self._failed is not None:
                return
            try:
                self._journal.write()
            except OSError as e:
                raise self._fail(e) from e

    def flush_if_due(self) -> None:
        """Close the open chunk if it has been open ``flush_wall_s`` of wall time (call it when
        no message comes, so that a quiet link does not keep data unwritten)."""
        if (
            self._flush_wall_s
            and self._w.n
            and time.monotonic() - self._wall0 >= self._flush_wall_s
        ):
            self.flush()

    def _flush_chunk(self) -> None:
        n = self._w.n
        if not n or self._f.closed:
            return
        with signals_held():
            try:
                self._w.flush_chunk()  # the chunk, its message indexes; flushed to the OS
                if self._fsync:
                    os.fsync(self._f.fileno())
                if self._journal is not None:  # the chunk is out: the journal starts again
                    self._journal.restart(self._msg_count + n)
            except OSError as e:
                raise self._fail(e) from e
            self._msg_count += n
            self._disk_lt = self._last_lt

    # ------------------------------------------------------------------ closing
    def close(self) -> None:
        """Write the last chunk, the summary and the footer. Safe to call more than once, from
        ``finally`` or from a signal handler (a re-entrant call returns at once)."""
        if self._closed or self._closing:
            return
        self._closing = True
        done = False
        try:
            with self._lock, signals_held():
                if not self._f.closed and self._failed is None:
                    self._flush_chunk()
                    try:
                        self._w.finish()
                        if self._fsync:
                            os.fsync(self._f.fileno())
                    except OSError as e:
                        raise self._fail(e) from e
                    done = True
        finally:
            self._closed = True
            if self._journal is not None:  # a finalised log needs no journal
                self._journal.close(remove=done)
            try:
                self._f.close()
            except OSError:  # the buffer could not go out: the write error was already raised
                pass
            finally:
                atexit.unregister(self._atexit)

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def message_count(self) -> int:
        """Messages written so far (including the open chunk)."""
        return self._msg_count + self._w.n

    def __enter__(self) -> LogWriter:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
