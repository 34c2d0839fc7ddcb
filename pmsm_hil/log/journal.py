"""The journal beside a run's log: what the host received since the log's last chunk, on disk.

The log's chunks stay large (compressed, quick to read); a killed host would lose its open chunk.
So each message added to the open chunk is also appended, as a plain MCAP message record, to
``LOG.journal``, written to the OS at the end of every receive batch (``LogWriter.flush_batch``):
one ``write`` of the batch's records. When the chunk has gone to the OS the journal starts again
(truncated, then its prologue). A finalised log removes its journal.

The journal is itself an MCAP stream without summary (magic, header, a ``journal`` metadata record
with ``base_messages``: the messages the log held when the journal started, then schemas, channels,
messages), readable by `mcap`'s stream reader. ``read_journal`` gives the messages the log does
not hold: a kill between the chunk's write and the journal's restart leaves the chunk's messages
in both, the first ``log messages - base_messages`` of the journal. ``pmsm-hil log recover``
(``rewrite_log``) appends them to the recovered log.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass

from mcap.records import Channel, Header, Metadata, Schema

from pmsm_hil.log.mcap_file import MAGIC, encode_record

__all__ = ["Journal", "JournalMessage", "journal_path", "read_journal"]


def journal_path(log_path: str | os.PathLike) -> str:
    return os.fspath(log_path) + ".journal"


class Journal:
    """The writer's side; not thread-safe (the LogWriter calls it under its lock)."""

    def __init__(self, log_path: str, profile: str, library: str):
        self.path = journal_path(log_path)
        self._profile, self._library = profile, library
        self._defs: list[Schema | Channel] = []
        # records not yet written (the writer's batch path appends message records here)
        self.pending: list[bytes] = []
        self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self.restart(0)

    def define(self, rec: Schema | Channel) -> None:
        """A schema or channel the journal's messages use (kept across restarts)."""
        self._defs.append(rec)
        self.pending.append(encode_record(rec))

    def add_record(self, record: bytes) -> None:
        """A message record as the log's chunk holds it (the same octets)."""
        self.pending.append(record)

    def write(self) -> None:
        """The records added since the last write, to the OS in one write."""
        if self.pending:
            data = b"".join(self.pending)
            self.pending.clear()
            while data:
                data = data[os.write(self._fd, data) :]

    def restart(self, base_messages: int) -> None:
        """The log holds ``base_messages`` on disk: start again from the prologue."""
        self.pending.clear()
        os.ftruncate(self._fd, 0)
        os.lseek(self._fd, 0, os.SEEK_SET)
        recs = [
            Header(self._profile, self._library),
            Metadata("journal", {"base_messages": str(base_messages)}),
            *self._defs,
        ]
        self.pending.append(MAGIC + b"".join(encode_record(r) for r in recs))
        self.write()

    def close(self, remove: bool) -> None:
        with contextlib.suppress(OSError):
            os.close(self._fd)
            if remove:
                os.unlink(self.path)


@dataclass
class JournalMessage:
    topic: str
    log_time: int
    data: bytes


def read_journal(log_path: str | os.PathLike, log_messages: int) -> list[JournalMessage]:
    """The messages of ``LOG.journal`` that the log (holding ``log_messages``) does not; [] when
    there is no journal. Reads up to the first incomplete record."""
    from mcap.records import Message
    from mcap.stream_reader import StreamReader

    path = journal_path(log_path)
    if not os.path.isfile(path):
        return []
    topics: dict[int, str] = {}
    out: list[JournalMessage] = []
    base = log_messages
    with open(path, "rb") as f, contextlib.suppress(Exception):  # an unfinished stream's end
        for rec in StreamReader(f).records:
            if isinstance(rec, Metadata) and rec.name == "journal":
                base = int(rec.metadata.get("base_messages", log_messages))
            elif isinstance(rec, Channel):
                topics[rec.id] = rec.topic
            elif isinstance(rec, Message) and rec.channel_id in topics:
                out.append(JournalMessage(topics[rec.channel_id], rec.log_time, rec.data))
    return out[max(0, log_messages - base) :]
