"""MCAP log reader: topics as numpy columns, metadata, attachments; also unfinalised files.

    log = read_log("run.mcap")
    tel = log.topic("/pmsm/telemetry")      # {"t_s": array, "speed_rpm": array, ...}
    log.metadata["run"]["seed"], log.attachment("profile.yaml").text
    log = read_log("run.mcap", topics={"/pmsm/telemetry": ("t_s", "speed_rpm"), "/pmsm/events": None})

The file is read front to back, record by record and chunk by chunk (never whole), so a log whose
writer was killed gives every message of every chunk that reached the disk; ``log.finalised``
tells whether the summary and footer are there. With ``topics`` only those topics (and of each only
the fields named; ``None``: all) are decoded, chunk by chunk into columns, so the memory held is
what is asked for; in a finalised file (its summary names every channel) a chunk whose message
indexes hold none of the asked topics is not even decompressed (``log.chunks_read``,
``log.chunks_skipped``). A topic not asked for is read on first use by another pass over the file.
Flat schemas (primitives and strings: all of ours, and any other such ros2msg) are decoded by the
project's CDR codec, vectorised with numpy (pmsm_hil.log.columns); anything else falls back to
``mcap_ros2``'s decoder.

The records are read by the ``mcap`` library's record classes and chunk decompression; what is
kept here is what its readers cannot do fast enough (docs/log-format.md, "Reading: the decision";
benchmarks/log_reader.py): the walk over the top-level records without materialising every
message-index entry, and the numpy gather and decode of the messages through the chunks' indexes.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Mapping

import numpy as np

from pmsm_hil.log.parse import Attachment, LogFormatError, Sink, Wanted, _Chan, _Parser, _Schema
from pmsm_hil.log.schemas import PRIMITIVES, TOPICS, Codec, FieldDef, TopicDef, codec_for
from pmsm_hil.names import did_you_mean

__all__ = ["Attachment", "Log", "LogFormatError", "merge_topics", "read_log", "rewrite_log"]

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
        self.chunks_read = 0  # chunks decompressed
        self.chunks_skipped = 0  # chunks left compressed: none of the asked topics in them
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
        """Columns of a topic, one numpy array per field (those asked for in ``read_log``),
        ordered by log time (stable).

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
        if not ch.wanted:  # not asked for: one more pass over the file for it alone
            other = read_log(self.path, topics=[name])
            self._cache[name] = other.topic(name)
            self._times[name] = other._times[name]
            return self._cache[name]
        if ch.error:
            raise ValueError(ch.error)
        codec = self._codec(ch)
        if codec is None:
            lt = np.concatenate(ch.lts) if ch.lts else np.empty(0, dtype=np.uint64)
            ch.lts = []
            cols = self._decode_fallback(ch, ch.var_data)
        else:
            self._check_fields(ch, codec.names)
            lt, cols = self._assemble(ch, codec)
        if len(lt) > 1 and np.any(lt[1:] < lt[:-1]):
            order = np.argsort(lt, kind="stable")
            lt = lt[order]
            cols = {k: v[order] for k, v in cols.items()}
        self._cache[name] = cols
        self._times[name] = lt
        return cols

    def _check_fields(self, ch: _Chan, known: Iterable[str]) -> None:
        """A field asked for in ``read_log(topics={topic: fields})`` that the topic's schema in
        this file does not have is a KeyError naming it (a misspelt field would otherwise be left
        out without a word)."""
        known = list(known)
        # a field of the project's own schema for the topic that this file lacks (a log of an
        # older pmsm-hil) is left out as before: only a name known to neither is an error
        contract = TOPICS.get(ch.topic)
        ours = {f.name for f in contract.fields} if contract is not None else set()
        unknown = [f for f in ch.fields or () if f not in known and f not in ours]
        if unknown:
            hint = did_you_mean(unknown[0], known) if len(unknown) == 1 else ""
            raise KeyError(
                f"{self.path}: {ch.topic} has no field {', '.join(map(repr, unknown))}{hint} "
                f"(fields: {', '.join(known)})"
            )

    @staticmethod
    def _assemble(ch: _Chan, codec: Codec) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """The decoded batches of a channel as whole columns: the columns allocated for the
        count in the summary, else the batches joined one column at a time."""
        empty = codec.empty()
        names = [k for k in codec.names if ch.fields is None or k in ch.fields]
        if ch.out_lt is not None and not ch.parts and ch.filled == len(ch.out_lt):
            lt, cols = ch.out_lt, {k: ch.out[k] for k in names}
            ch.out_lt, ch.out = None, {}
            return lt, cols
        if ch.out_lt is not None:  # fewer or more messages than the statistics said
            ch.parts = {
                k: [(ch.out_lt if k == "" else ch.out[k])[: ch.filled], *ch.parts.get(k, [])]
                for k in ["", *names]
            }
            ch.out_lt, ch.out = None, {}
        cols = {}
        for k in ["", *names]:
            parts = ch.parts.pop(k, [])
            cols[k] = np.concatenate(parts) if parts else empty.get(k, np.empty(0, np.uint64))
            del parts  # the batches go as each column is joined
        return cols.pop("").astype(np.uint64), cols

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
        self._check_fields(ch, names)
        cols = {}
        for n in names:
            if ch.fields is not None and n not in ch.fields:
                continue
            vals = [getattr(m, n) for m in msgs]
            arr = np.array(vals) if all(isinstance(v, (int, float, bool)) for v in vals) else None
            if arr is None:
                arr = np.empty(len(vals), dtype=object)
                arr[:] = vals
            cols[n] = arr
        return cols


def path_problem(path: str | os.PathLike, what: str = "") -> str | None:
    """Why ``path`` cannot be opened as a log, in a user's words (None: it is a file).
    ``what`` names the option that gave it (``--holdout``)."""
    label = f"{what} {os.fspath(path)}" if what else os.fspath(path)
    if not os.fspath(path):
        return f"{what + ' ' if what else ''}'': an empty name; give the log's path"
    if not os.path.exists(path):
        return f"{label}: no such file"
    if os.path.isdir(path):
        return f"{label}: is a directory, not a log (give the .mcap file in it)"
    if not os.path.isfile(path):  # a FIFO, a device: no size to read, no place to seek
        return f"{label}: not a regular file (a pipe or a device); give the .mcap file"
    if os.path.getsize(path) == 0:
        return f"{label}: the file is empty (0 octets): no run was recorded"
    return None


def read_log(
    path: str | os.PathLike, topics: Iterable[str] | Wanted | None = None, sink: Sink | None = None
) -> Log:
    """Read an MCAP log (finalised or not). Raises LogFormatError if it is not MCAP at all.

    ``topics``: None reads every topic; names (``["/pmsm/params"]``) read only those; a mapping
    of names to field names (or None: all fields) reads only those fields of them.
    ``sink(topic, octets, starts, sizes, log_times)``: also called with each batch of an asked
    topic's messages as it is read, in file order (their CDR data at ``starts`` in ``octets``,
    valid during the call only): a whole file streamed with only the asked fields held."""
    path = os.fspath(path)
    if topics is not None and not isinstance(topics, Mapping):
        topics = {t: None for t in ([topics] if isinstance(topics, str) else topics)}
    log = Log(path)
    with open(path, "rb") as f:
        size = os.fstat(f.fileno()).st_size
        _Parser(log, f, size, topics, sink).run()
    return log


def merge_topics(*wants: Wanted) -> dict[str, tuple | None]:
    """The topics (and fields) that several readers ask for, as one ``topics=`` for read_log."""
    out: dict[str, tuple | None] = {}
    for want in wants:
        for topic, fields in want.items():
            before = out.get(topic, ())
            if fields is None or before is None:
                out[topic] = None
            else:
                out[topic] = tuple(dict.fromkeys((*before, *fields)))
    return out


def rewrite_log(src: str | os.PathLike, dst: str | os.PathLike) -> Log:
    """Read ``src`` (finalised or not) and write its messages, metadata and attachments to a new,
    finalised ``dst`` (e.g. to open a log of a killed run in Foxglove), then the messages of its
    journal that it does not hold (pmsm_hil.log.journal). Topics whose schema is not flat are left
    out (listed in the returned log's ``problems``).

    Streamed: a first pass takes the metadata, attachments and channels (no message decoded), the
    second writes each chunk's messages as they are read, their CDR data and log times as they
    are, so the memory held is one chunk and the device times (``t_s``) of the returned log,
    whatever the length of the log (an hour at the contract's rates: some 50 MiB)."""
    from pmsm_hil.log.journal import read_journal
    from pmsm_hil.log.writer import LogWriter

    head = read_log(src, topics=[])
    flat, extra, not_flat = [], [], []
    for topic in head.topics:
        codec = head._codec(head._by_topic[topic])
        if codec is None:
            not_flat.append(f"{topic}: schema is not flat; not rewritten")
            continue
        flat.append(topic)
        if topic not in TOPICS:
            extra.append(codec.topic)
    meta = {k: v for k, v in head.metadata.items() if k != "log"}
    atts = [(a.name, a.media_type, a.data) for a in head.attachments]
    offset_ns = int(head.metadata.get("log", {}).get("log_time_offset_ns", "0") or 0)
    extra_names = {t.topic for t in extra}
    with LogWriter(dst, meta, atts, topics=extra, wall_start_s=offset_ns / 1e9 or None) as w:

        def write(topic: str, octets: np.ndarray, starts, sizes, lts) -> None:
            data = octets.data  # a memoryview of the chunk: a slice per message, no copy
            w.write_encoded_many(
                topic,
                lts.tolist(),
                (data[a : a + n] for a, n in zip(starts.tolist(), sizes.tolist(), strict=True)),
            )

        log = read_log(src, topics={t: ("t_s",) for t in flat}, sink=write)
        log.problems += not_flat
        for m in read_journal(src, sum(log.counts.values())):  # received after the last chunk
            if m.topic in TOPICS or m.topic in extra_names:
                w.write_encoded(m.topic, m.log_time, m.data)
    return log
