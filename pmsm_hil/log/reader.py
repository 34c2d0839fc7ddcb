"""MCAP log reader: topics as numpy columns, metadata, attachments; also unfinalised files.

    log = read_log("run.mcap")
    tel = log.topic("/pmsm/telemetry")      # {"t_s": array, "speed_rpm": array, ...}
    log.metadata["run"]["seed"], log.attachment("profile.yaml").text

The file is read front to back (the summary section is not needed), so a log whose writer was
killed gives every message of every chunk that reached the disk; ``log.finalised`` tells whether
the summary and footer are there. Flat schemas (primitives and strings: all of ours, and any other
such ros2msg) are decoded by the project's CDR codec, vectorised with numpy for fixed layouts;
anything else falls back to ``mcap_ros2``'s decoder.

The records are read by the ``mcap`` library's record classes and chunk decompression; what is
kept here is what its readers cannot do fast enough (docs/log-format.md, "Reading: the decision";
benchmarks/log_reader.py): the walk over the top-level records without materialising every
message-index entry, and the numpy gather and decode of the messages through the chunks' indexes.
"""

from __future__ import annotations

import io
import os
import re
import struct
import zlib
from dataclasses import dataclass, field

import numpy as np
from mcap import records as mr
from mcap.data_stream import ReadDataStream
from mcap.stream_reader import get_chunk_data_stream

from pmsm_hil.log.schemas import PRIMITIVES, TOPICS, Codec, FieldDef, TopicDef, codec_for
from pmsm_hil.log.writer import MCAP_MAGIC

__all__ = ["Attachment", "Log", "LogFormatError", "read_log", "rewrite_log"]

_REC = struct.Struct("<BQ")
_U16 = struct.Struct("<H").unpack_from
_U32 = struct.Struct("<I").unpack_from
_MSG = struct.Struct("<HIQQ").unpack_from


def _read(cls, content) -> object:
    """One record's content (without opcode and length) parsed by the mcap library."""
    return cls.read(ReadDataStream(io.BytesIO(content)))


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
    lts: list = field(default_factory=list)  # arrays of log times (uint64)
    fixed_blocks: list = field(default_factory=list)  # 2-D uint8 arrays (n, size): fixed layout
    var_data: list = field(default_factory=list)  # bytes per message: other layouts
    count: int = 0


@dataclass
class _Schema:
    id: int
    name: str
    encoding: str
    data: bytes


_MSG_LINE = re.compile(r"^\s*([A-Za-z][\w/]*)\s+([a-z][a-z0-9_]*)\s*$")


def _flat_topicdef(topic: str, schema: _Schema) -> TopicDef | None:
    """A TopicDef for a ros2msg of primitives and strings only (else None)."""
    if schema.encoding != "ros2msg":
        return None
    fields = []
    for line in schema.data.decode("utf-8", "replace").splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith("="):  # a dependency section follows: not flat
            return None
        if "=" in line:  # a constant: not part of the data
            continue
        m = _MSG_LINE.match(line)
        if not m:
            return None
        typ, name = m.groups()
        if typ != "string" and typ not in PRIMITIVES:
            return None
        fields.append(FieldDef(name, typ))
    if not fields:
        return None
    return TopicDef(topic, schema.name, tuple(fields))


class Log:
    """A read MCAP log."""

    def __init__(self, path: str):
        self.path = path
        self.profile = ""
        self.library = ""
        self.metadata: dict[str, dict[str, str]] = {}
        self.attachments: list[Attachment] = []
        self.finalised = False  # summary and footer present
        self.truncated = False  # the file ends inside a record
        self.problems: list[str] = []
        self._schemas: dict[int, _Schema] = {}
        self._chans: dict[int, _Chan] = {}
        self._by_topic: dict[str, _Chan] = {}
        self._codecs: dict[int, Codec | None] = {}
        self._cache: dict[str, dict[str, np.ndarray]] = {}
        self._times: dict[str, np.ndarray] = {}

    def __repr__(self) -> str:
        counts = ", ".join(f"{t}: {n}" for t, n in self.counts.items())
        state = (
            "finalised" if self.finalised else ("truncated" if self.truncated else "not finalised")
        )
        return f"Log({self.path!r}, {state}, {counts})"

    # ------------------------------------------------------------------ queries
    @property
    def topics(self) -> list[str]:
        return list(self._by_topic)

    @property
    def counts(self) -> dict[str, int]:
        return {t: c.count for t, c in self._by_topic.items()}

    def schema(self, topic: str) -> tuple[str, str, str]:
        """(schema name, schema encoding, schema text) of a topic in the file."""
        ch = self._by_topic[topic]
        s = self._schemas.get(ch.schema_id)
        return (s.name, s.encoding, s.data.decode("utf-8", "replace")) if s else ("", "", "")

    def attachment(self, name: str) -> Attachment | None:
        for a in self.attachments:
            if a.name == name:
                return a
        return None

    def log_times_ns(self, topic: str) -> np.ndarray:
        """MCAP log times (ns, uint64) of the topic's messages, in the order of ``topic()``."""
        self.topic(topic)
        return self._times.get(topic, np.empty(0, dtype=np.uint64))

    def topic(self, name: str) -> dict[str, np.ndarray]:
        """Columns of a topic, one numpy array per field, ordered by log time (stable).

        A topic of the log contract that has no message in the file gives empty columns; any other
        missing topic raises KeyError.
        """
        if name in self._cache:
            return self._cache[name]
        ch = self._by_topic.get(name)
        if ch is None:
            if name in TOPICS:
                return codec_for(name).empty()
            raise KeyError(
                f"{self.path}: no topic {name!r} (topics: {', '.join(self.topics) or 'none'})"
            )
        cols, lt = self._decode(ch)
        if len(lt) > 1 and np.any(np.diff(lt.astype(np.int64)) < 0):
            order = np.argsort(lt, kind="stable")
            lt = lt[order]
            cols = {k: v[order] for k, v in cols.items()}
        self._cache[name] = cols
        self._times[name] = lt
        return cols

    def _codec(self, ch: _Chan) -> Codec | None:
        if ch.id in self._codecs:
            return self._codecs[ch.id]
        codec = None
        s = self._schemas.get(ch.schema_id)
        if ch.encoding == "cdr" and s is not None:
            ours = TOPICS.get(ch.topic)
            if (
                ours is not None
                and s.name == ours.schema_name
                and s.data.decode("utf-8", "replace") == ours.msgdef
            ):
                codec = codec_for(ch.topic)
            else:
                td = _flat_topicdef(ch.topic, s)
                if td is not None and td.fields[0].name == "t_s" and td.fields[0].type == "float64":
                    codec = Codec(td)
        self._codecs[ch.id] = codec
        return codec

    def _decode(self, ch: _Chan) -> tuple[dict[str, np.ndarray], np.ndarray]:
        lt = np.concatenate(ch.lts).astype(np.uint64) if ch.lts else np.empty(0, dtype=np.uint64)
        codec = self._codec(ch)
        if codec is not None and codec.fixed:
            blocks = list(ch.fixed_blocks)
            if ch.var_data:  # then fixed_blocks is empty (see _Parser._add_var)
                if any(len(d) != codec.size for d in ch.var_data):
                    raise ValueError(
                        f"{self.path}: {ch.topic}: messages of the wrong size for "
                        f"{codec.topic.schema_name}"
                    )
                blocks.append(
                    np.frombuffer(b"".join(ch.var_data), dtype=np.uint8).reshape(-1, codec.size)
                )
            buf = np.concatenate(blocks) if blocks else np.empty((0, codec.size), np.uint8)
            if buf.shape[1] != codec.size:
                raise ValueError(
                    f"{self.path}: {ch.topic}: message size {buf.shape[1]} does not match "
                    f"the schema ({codec.size})"
                )
            return codec.decode_columns(buf.tobytes(), len(buf)), lt
        datas = ch.var_data + [bytes(r) for b in ch.fixed_blocks for r in b]
        if codec is not None:
            sizes = np.array([len(d) for d in datas], dtype=np.int64)
            return codec.decode_columns(b"".join(datas), len(datas), sizes), lt
        return self._decode_fallback(ch, datas), lt

    def _decode_fallback(self, ch: _Chan, datas: list[bytes]) -> dict[str, np.ndarray]:
        from mcap.records import Schema
        from mcap_ros2.decoder import DecoderFactory

        s = self._schemas.get(ch.schema_id)
        if s is None:
            raise KeyError(f"{self.path}: {ch.topic} has no schema")
        dec = DecoderFactory().decoder_for(
            ch.encoding, Schema(id=s.id, name=s.name, encoding=s.encoding, data=s.data)
        )
        if dec is None:
            raise ValueError(
                f"{self.path}: {ch.topic}: cannot decode {ch.encoding} / {s.encoding} messages"
            )
        msgs = [dec(d) for d in datas]
        if not msgs:
            return {}
        names = list(getattr(type(msgs[0]), "__slots__", ()) or vars(msgs[0]).keys())
        cols = {}
        for n in names:
            vals = [getattr(m, n) for m in msgs]
            arr = np.array(vals) if all(isinstance(v, (int, float, bool)) for v in vals) else None
            if arr is None:
                arr = np.empty(len(vals), dtype=object)
                arr[:] = vals
            cols[n] = arr
        return cols


# ----------------------------------------------------------------------------------- parsing


class _Parser:
    def __init__(self, log: Log, buf: bytes):
        self.log = log
        self.buf = buf
        self.mv = memoryview(buf)

    # records that may appear in the data section or inside chunks
    def _schema(self, c: memoryview) -> None:
        r = _read(mr.Schema, c)
        self.log._schemas[r.id] = _Schema(r.id, r.name, r.encoding, bytes(r.data))

    def _channel(self, c: memoryview) -> None:
        r = _read(mr.Channel, c)
        if r.id not in self.log._chans:
            ch = _Chan(r.id, r.topic, r.schema_id, r.message_encoding, dict(r.metadata))
            self.log._chans[r.id] = ch
            self.log._by_topic.setdefault(r.topic, ch)

    def run(self) -> None:
        log, buf, mv = self.log, self.buf, self.mv
        if not buf.startswith(MCAP_MAGIC):
            raise LogFormatError(f"{log.path}: not an MCAP file (bad magic)")
        n = len(buf)
        p = len(MCAP_MAGIC)
        pending: tuple | None = None  # (chunk records, {channel: index array}) awaiting indexes
        while True:
            if p + 9 > n:
                if p < n:
                    log.truncated = True
                break
            op, length = _REC.unpack_from(buf, p)
            end = p + 9 + length
            if end > n:
                log.truncated = True
                break
            c = mv[p + 9 : end]
            if op == 0x07 and pending is not None:  # message index of the pending chunk
                (cid,) = _U16(c, 0)
                (ln,) = _U32(c, 2)
                pending[1][cid] = np.frombuffer(c[6 : 6 + ln], dtype="<u8").reshape(-1, 2)
                p = end
                continue
            if pending is not None:
                self._chunk_done(*pending)
                pending = None
            if op == 0x06:
                pending = (self._open_chunk(c), {})
            elif op == 0x05:
                cid, _, lt, _ = _MSG(c, 0)
                self._add_one(cid, lt, bytes(c[22:]))
            elif op == 0x03:
                self._schema(c)
            elif op == 0x04:
                self._channel(c)
            elif op == 0x01:
                r = _read(mr.Header, c)
                log.profile, log.library = r.profile, r.library
            elif op == 0x0C:
                r = _read(mr.Metadata, c)
                log.metadata.setdefault(r.name, {}).update(r.metadata)
            elif op == 0x09:
                self._attachment(c)
            elif op == 0x0F:  # data end: the summary follows
                log.finalised = self._has_footer()
                break
            p = end
        if pending is not None:
            self._chunk_done(*pending)

    def _has_footer(self) -> bool:
        buf = self.buf
        if len(buf) < 8 + 29 or not buf.endswith(MCAP_MAGIC):
            return False
        return buf[-8 - 29] == 0x02

    def _attachment(self, c: memoryview) -> None:
        r = _read(mr.Attachment, c)  # the library skips the CRC: checked here
        (crc,) = _U32(c, len(c) - 4)
        if crc and crc != zlib.crc32(c[: len(c) - 4]):
            self.log.problems.append(f"attachment {r.name!r}: CRC mismatch")
        self.log.attachments.append(
            Attachment(r.name, r.media_type, bytes(r.data), r.log_time, r.create_time)
        )

    def _open_chunk(self, c: memoryview) -> bytes | None:
        try:
            chunk = _read(mr.Chunk, c)
            if chunk.compression not in ("", "zstd", "lz4"):
                self.log.problems.append(
                    f"chunk with unknown compression {chunk.compression!r} skipped"
                )
                return None
            stream, n = get_chunk_data_stream(chunk, validate_crc=True)
            records = stream.read(n)
        except Exception as e:  # a damaged chunk (CRC, compression): keep the rest of the file
            self.log.problems.append(f"chunk could not be read ({e}); skipped")
            return None
        if len(records) != chunk.uncompressed_size:
            self.log.problems.append("chunk size mismatch; skipped")
            return None
        return records

    def _add_one(self, cid: int, lt: int, data: bytes) -> None:
        ch = self.log._chans.get(cid)
        if ch is None:
            self.log.problems.append(f"message on unknown channel {cid} skipped")
            return
        ch.lts.append(np.array([lt], dtype=np.uint64))
        self._add_var(ch, [data])
        ch.count += 1

    def _chunk_done(self, records: bytes | None, indexes: dict[int, np.ndarray]) -> None:
        if records is None:
            return
        if indexes and self._chunk_indexed(records, indexes):
            return
        self._chunk_sequential(records)

    def _chunk_sequential(self, d: bytes) -> None:
        mv = memoryview(d)
        p, n = 0, len(d)
        unpack = _REC.unpack_from
        per: dict[int, tuple[list, list]] = {}
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
                    lst = per[cid] = ([], [])
                lst[0].append(lt)
                lst[1].append(d[p + 31 : e])
            elif op == 0x03:
                self._schema(mv[p + 9 : e])
            elif op == 0x04:
                self._channel(mv[p + 9 : e])
            p = e
        for cid, (lts, datas) in per.items():
            ch = self.log._chans.get(cid)
            if ch is None:
                self.log.problems.append(f"{len(lts)} messages on unknown channel {cid} skipped")
                continue
            ch.lts.append(np.array(lts, dtype=np.uint64))
            codec = self.log._codec(ch)
            if codec is not None and codec.fixed and all(len(x) == codec.size for x in datas):
                self._add_fixed(
                    ch, np.frombuffer(b"".join(datas), np.uint8).reshape(-1, codec.size)
                )
            else:
                self._add_var(ch, datas)
            ch.count += len(lts)

    # A channel keeps its messages either all as fixed-size blocks or (once one message did not
    # fit the fixed layout) all as separate data, so that their order is kept.
    @staticmethod
    def _add_fixed(ch: _Chan, block: np.ndarray) -> None:
        if ch.var_data:
            ch.var_data.extend(bytes(r) for r in block)
        else:
            ch.fixed_blocks.append(block)

    @staticmethod
    def _add_var(ch: _Chan, datas: list) -> None:
        if ch.fixed_blocks:
            ch.var_data.extend(bytes(r) for b in ch.fixed_blocks for r in b)
            ch.fixed_blocks = []
        ch.var_data.extend(datas)

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
                    return False
                continue
            offs = idx[:, 1].astype(np.int64)
            if offs.min() < 0 or offs.max() + 31 > n:
                return False
            lens = (
                arr[offs[:, None] + 1 + np.arange(8)]
                .copy()
                .view("<u8")
                .reshape(-1)
                .astype(np.int64)
            )
            ops = arr[offs]
            cids = arr[offs[:, None] + 9 + np.arange(2)].copy().view("<u2").reshape(-1)
            if np.any(ops != 0x05) or np.any(cids != cid) or np.any(offs + 9 + lens > n):
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
        mv = memoryview(d)
        for op, a, b in gaps:
            if op == 0x03:
                self._schema(mv[a + 9 : b])
            elif op == 0x04:
                self._channel(mv[a + 9 : b])
        for ch, idx, offs, lens in plans:
            ch.lts.append(idx[:, 0].astype(np.uint64))
            codec = self.log._codec(ch)
            size = int(lens[0]) - 22
            if codec is not None and codec.fixed and np.all(lens == lens[0]) and size == codec.size:
                self._add_fixed(ch, arr[offs[:, None] + 31 + np.arange(size)])
            else:
                self._add_var(
                    ch,
                    [
                        d[o + 31 : o + 9 + ln]
                        for o, ln in zip(offs.tolist(), lens.tolist(), strict=False)
                    ],
                )
            ch.count += len(offs)
        return True


def read_log(path: str | os.PathLike) -> Log:
    """Read an MCAP log (finalised or not). Raises LogFormatError if it is not MCAP at all."""
    path = os.fspath(path)
    with open(path, "rb") as f:
        buf = f.read()
    log = Log(path)
    _Parser(log, buf).run()
    return log


def rewrite_log(src: str | os.PathLike, dst: str | os.PathLike) -> Log:
    """Read ``src`` (finalised or not) and write its messages, metadata and attachments to a new,
    finalised ``dst`` (e.g. to open a log of a killed run in Foxglove). Topics whose schema is not
    flat are left out (listed in the returned log's ``problems``)."""
    from pmsm_hil.log.writer import LogWriter

    log = read_log(src)
    extra = []
    for topic in log.topics:
        codec = log._codec(log._by_topic[topic])
        if codec is not None and topic not in TOPICS:
            extra.append(codec.topic)
    meta = {k: v for k, v in log.metadata.items() if k != "log"}
    atts = [(a.name, a.media_type, a.data) for a in log.attachments]
    offset_ns = int(log.metadata.get("log", {}).get("log_time_offset_ns", "0") or 0)
    with LogWriter(dst, meta, atts, topics=extra, wall_start_s=offset_ns / 1e9 or None) as w:
        for topic in log.topics:
            if log._codec(log._by_topic[topic]) is None:
                log.problems.append(f"{topic}: schema is not flat; not rewritten")
                continue
            cols = log.topic(topic)
            if len(cols["t_s"]):
                w.write_many(topic, cols)
    return log
