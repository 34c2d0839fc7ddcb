"""The MCAP records of one log file: chunks built from message records, their indexes, the summary.

The records other than messages (header, schemas, channels, metadata, attachments, chunks, message
indexes, statistics, chunk / attachment / metadata indexes, summary offsets, data end, footer) are
encoded by the ``mcap`` library's record classes (``mcap.records``, their ``write``); a message
record is one ``struct.pack`` of its head followed by its data, kept as bytes in the open chunk
(the same bytes go to the journal, pmsm_hil.log.journal). The file's layout is the library
``Writer``'s (``chunk_size`` out of reach, data CRCs on): schema and channel records in the chunk of
the channel's first message, each chunk followed by its message indexes, metadata and attachments
outside the chunks as they are added, the summary repeating schemas and channels, then statistics,
chunk, attachment and metadata indexes and the summary offsets, with data-section and summary CRCs.
The work per message is a few list appends, so the library's per-message record objects, builder
calls and index tuples are not paid (docs/log-format.md, "Writing").
"""

from __future__ import annotations

import struct
import sys
import zlib
from array import array
from collections.abc import Callable
from typing import BinaryIO

from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

__all__ = ["MAGIC", "MESSAGE_HEAD", "McapFile", "encode_record"]

MAGIC = b"\x89MCAP0\r\n"
# a message record's head: opcode, record length, channel, sequence, log and publish time
MESSAGE_HEAD = struct.Struct("<BQHIQQ")
_INDEX_HEAD = struct.Struct("<BQHI")  # message index: opcode, length, channel, entries' octets
_LITTLE = sys.byteorder == "little"


def encode_record(rec: McapRecord) -> bytes:
    """One record's octets, as the library's ``Writer`` writes them."""
    b = RecordBuilder()
    rec.write(b)
    return bytes(b.end())


def _compressor(name: str) -> Callable[[bytes], bytes]:
    if name == "zstd":
        import zstandard

        return zstandard.compress  # the library's Writer's level
    if name == "lz4":
        import lz4.frame

        return lz4.frame.compress
    return bytes


class _Index:
    """One channel's entries in the open chunk (log time, offset in the chunk's records)."""

    __slots__ = ("offsets", "times")

    def __init__(self) -> None:
        self.times: list[int] = []
        self.offsets: list[int] = []

    def record(self, cid: int) -> bytes:
        n = len(self.times)
        pairs = array("Q", bytes(16 * n))
        pairs[0::2] = array("Q", self.times)
        pairs[1::2] = array("Q", self.offsets)
        if not _LITTLE:
            pairs.byteswap()
        return _INDEX_HEAD.pack(Opcode.MESSAGE_INDEX, 6 + 16 * n, cid, 16 * n) + pairs.tobytes()


class McapFile:
    """Writes the records of one MCAP file to ``stream`` (opened for writing, at its start).

    Not thread-safe: the LogWriter calls it under its lock."""

    def __init__(self, stream: BinaryIO, compression: str, profile: str, library: str):
        self._f = stream
        self._compression = compression
        self._compress = _compressor(compression)
        self._pos = 0  # octets written to the stream
        self._crc = 0  # data-section CRC
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self._counts: dict[int, int] = {}  # messages per channel, in the order of the first
        self._message_count = 0
        self._start_time = 0
        self._end_time = 0
        self._chunk_indexes: list[ChunkIndex] = []
        self._attachment_indexes: list[AttachmentIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        # the open chunk: its records (schemas and channels first met, messages), their octets,
        # its messages, per channel its index entries
        self._records: list[bytes] = []
        self.size = 0
        self.n = 0
        self._index: dict[int, _Index] = {}
        self._write(MAGIC + encode_record(Header(profile, library)))

    def _write(self, data: bytes) -> None:
        self._f.write(data)
        self._crc = zlib.crc32(data, self._crc)
        self._pos += len(data)

    # ------------------------------------------------------------------ records outside chunks
    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        rec = encode_record(Metadata(name=name, metadata=data))
        self._metadata_indexes.append(MetadataIndex(offset=self._pos, length=len(rec), name=name))
        self._write(rec)

    def add_attachment(
        self, create_time: int, log_time: int, name: str, media_type: str, data: bytes
    ) -> None:
        rec = encode_record(
            Attachment(
                create_time=create_time,
                log_time=log_time,
                name=name,
                media_type=media_type,
                data=data,
            )
        )
        self._attachment_indexes.append(
            AttachmentIndex(
                offset=self._pos,
                length=len(rec),
                create_time=create_time,
                log_time=log_time,
                data_size=len(data),
                name=name,
                media_type=media_type,
            )
        )
        self._write(rec)

    # ------------------------------------------------------------------ the open chunk
    def _add_definition(self, rec: bytes) -> None:
        self._records.append(rec)
        self.size += len(rec)

    def register_schema(self, name: str, encoding: str, data: bytes) -> Schema:
        schema = Schema(id=len(self.schemas) + 1, data=data, encoding=encoding, name=name)
        self.schemas[schema.id] = schema
        self._add_definition(encode_record(schema))
        return schema

    def register_channel(self, topic: str, message_encoding: str, schema_id: int) -> Channel:
        channel = Channel(
            id=len(self.channels) + 1,
            topic=topic,
            message_encoding=message_encoding,
            schema_id=schema_id,
            metadata={},
        )
        self.channels[channel.id] = channel
        self._add_definition(encode_record(channel))
        return channel

    def add_message(self, cid: int, sequence: int, log_time: int, data: bytes) -> bytes:
        """A message into the open chunk; returns its record (log_time = publish_time)."""
        rec = MESSAGE_HEAD.pack(5, 22 + len(data), cid, sequence, log_time, log_time) + data
        index = self._index.get(cid)
        if index is None:
            index = self._index[cid] = _Index()
        index.times.append(log_time)
        index.offsets.append(self.size)
        self._records.append(rec)
        self.size += len(rec)
        self.n += 1
        return rec

    def add_records(self, cid: int, log_times: list[int], records: bytes, size: int) -> None:
        """Message records of one channel made by the caller (pmsm_hil.log.blocks: the octets
        ``add_message`` makes), each ``size`` octets, into the open chunk."""
        index = self._index.get(cid)
        if index is None:
            index = self._index[cid] = _Index()
        index.times.extend(log_times)
        index.offsets.extend(range(self.size, self.size + len(records), size))
        self._records.append(records)
        self.size += len(records)
        self.n += len(log_times)

    def flush_chunk(self) -> None:
        """The open chunk and its message indexes to the stream (nothing without messages);
        then the stream is flushed to the OS."""
        if not self.n:
            self._f.flush()
            return
        data = b"".join(self._records)
        start = min(min(ix.times) for ix in self._index.values())
        end = max(max(ix.times) for ix in self._index.values())
        compressed = self._compress(data)
        chunk = encode_record(
            Chunk(
                compression=self._compression,
                data=compressed,
                message_start_time=start,
                message_end_time=end,
                uncompressed_crc=zlib.crc32(data),
                uncompressed_size=len(data),
            )
        )
        chunk_at = self._pos
        index_at = chunk_at + len(chunk)
        offsets: dict[int, int] = {}
        indexes: list[bytes] = []
        at = index_at
        for cid, ix in self._index.items():
            offsets[cid] = at
            rec = ix.record(cid)
            indexes.append(rec)
            at += len(rec)
            self._counts[cid] = self._counts.get(cid, 0) + len(ix.times)
        self._write(chunk + b"".join(indexes))
        self._f.flush()
        self._chunk_indexes.append(
            ChunkIndex(
                message_start_time=start,
                message_end_time=end,
                chunk_start_offset=chunk_at,
                chunk_length=len(chunk),
                message_index_offsets=offsets,
                message_index_length=at - index_at,
                compression=self._compression,
                compressed_size=len(compressed),
                uncompressed_size=len(data),
            )
        )
        if self._message_count == 0:
            self._start_time = start
        else:
            self._start_time = min(self._start_time, start)
        self._end_time = max(self._end_time, end)
        self._message_count += self.n
        self._records = []
        self._index = {}
        self.size = 0
        self.n = 0

    # ------------------------------------------------------------------ the end
    def finish(self) -> None:
        """The last chunk, the data end, the summary, the footer and the closing magic."""
        self.flush_chunk()
        self._write(encode_record(DataEnd(self._crc)))
        summary_start = self._pos
        groups: list[tuple[Opcode, list[McapRecord]]] = [
            (Opcode.SCHEMA, list(self.schemas.values())),
            (Opcode.CHANNEL, list(self.channels.values())),
            (
                Opcode.STATISTICS,
                [
                    Statistics(
                        attachment_count=len(self._attachment_indexes),
                        channel_count=len(self.channels),
                        channel_message_counts=dict(self._counts),
                        chunk_count=len(self._chunk_indexes),
                        message_count=self._message_count,
                        metadata_count=len(self._metadata_indexes),
                        message_start_time=self._start_time,
                        message_end_time=self._end_time,
                        schema_count=len(self.schemas),
                    )
                ],
            ),
            (Opcode.CHUNK_INDEX, list(self._chunk_indexes)),
            (Opcode.ATTACHMENT_INDEX, list(self._attachment_indexes)),
            (Opcode.METADATA_INDEX, list(self._metadata_indexes)),
        ]
        parts: list[bytes] = []
        offsets: list[SummaryOffset] = []
        length = 0
        for opcode, recs in groups:
            group = b"".join(encode_record(r) for r in recs)
            offsets.append(
                SummaryOffset(
                    group_opcode=opcode, group_start=summary_start + length, group_length=len(group)
                )
            )
            parts.append(group)
            length += len(group)
        offsets_start = summary_start + length
        parts.extend(encode_record(o) for o in offsets)
        summary = b"".join(parts)
        footer_head = struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, offsets_start)
        crc = zlib.crc32(footer_head, zlib.crc32(summary))
        self._f.write(summary)
        self._f.write(
            encode_record(
                Footer(
                    summary_start=summary_start, summary_offset_start=offsets_start, summary_crc=crc
                )
            )
            + MAGIC
        )
        self._pos += len(summary) + 29 + len(MAGIC)
        self._f.flush()
