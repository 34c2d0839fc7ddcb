"""Many messages of one fixed-layout topic made at once (pmsm_hil.log.writer's ``message_block`` /
``write_block``): their MCAP message records as one numpy array, the sequence numbers filled in as
they are written. The octets are those of ``write``, message for message (tests/test_log_blocks.py).

A record is the message head (opcode, record length, channel, sequence, log time, publish time;
pmsm_hil.log.mcap_file's ``MESSAGE_HEAD``) followed by the CDR data, packed: a structured dtype
with those fields at their offsets makes a block of records in a few array assignments instead of
a ``struct.pack`` per message.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import Any

import numpy as np

from pmsm_hil.log.mcap_file import MESSAGE_HEAD
from pmsm_hil.log.schemas import CDR_LE_HEADER, Codec

__all__ = [
    "CDR_HEADER",
    "HEAD_SIZE",
    "MessageBlock",
    "cdr_from_columns",
    "log_times",
    "record_dtype",
]

HEAD_SIZE = (
    MESSAGE_HEAD.size
)  # opcode 1, record length 8, channel 2, sequence 4, log and publish time 8
CDR_HEADER = np.frombuffer(CDR_LE_HEADER, np.uint8)  # the encapsulation header as octets


@functools.lru_cache(maxsize=64)
def record_dtype(data_size: int) -> np.dtype:
    """A message record of ``data_size`` octets of data, little-endian, unaligned."""
    return np.dtype(
        {
            "names": ["op", "length", "channel", "seq", "log_time", "publish_time", "data"],
            "formats": ["u1", "<u8", "<u2", "<u4", "<u8", "<u8", (np.void, data_size)],
            "offsets": [0, 1, 9, 11, 15, 23, HEAD_SIZE],
            "itemsize": HEAD_SIZE + data_size,
        }
    )


def log_times(topic: str, t_s: Any, offset_ns: int) -> np.ndarray:
    """Device times (s) -> log times (ns, int64): ``round(t_s * 1e9) + offset_ns`` as ``write``
    makes them (round half to even, as Python's ``round``); ValueError names the topic when a time
    is not finite or negative."""
    t = np.asarray(t_s, dtype=np.float64).reshape(-1)
    if t.size and not (t.min() >= 0.0 and t.max() < np.inf):  # NaN fails both
        bad = t[~(np.isfinite(t) & (t >= 0))][0]
        raise ValueError(f"{topic}: t_s = {float(bad)!r} is not a device time (finite, >= 0 s)")
    ns = np.rint(t * 1e9).astype(np.int64)
    if offset_ns:
        ns += offset_ns
    return ns


def cdr_from_columns(topic: str, codec: Codec, cols: Mapping[str, Any], count: int) -> np.ndarray:
    """CDR data of ``count`` messages (the codec's fixed layout, encapsulation header included)
    from columns: ``t_s`` and any fields; a field not given is its default, as for ``write``."""
    assert codec.dtype is not None  # a fixed layout
    recs = np.zeros(count, dtype=codec.dtype)
    recs.view(np.uint8).reshape(count, -1)[:, :4] = CDR_HEADER
    recs["t_s"] = np.asarray(cols["t_s"], dtype=np.float64).reshape(-1)
    for f in codec.fields[1:]:
        col = cols.get(f.name)
        if col is None:
            recs[f.name] = f.default
            continue
        arr = np.asarray(col)
        if arr.shape != (count,) and arr.ndim != 0:
            raise ValueError(
                f"{topic}.{f.name}: {arr.shape[0] if arr.ndim else 1} values for {count} rows"
            )
        if f.type == "bool":
            arr = arr.astype(bool)
        elif f.type not in ("float32", "float64"):
            info = np.iinfo(recs[f.name].dtype)
            if arr.size and (np.any(arr < info.min) or np.any(arr > info.max)):
                raise ValueError(f"{topic}.{f.name}: values outside the {f.type} range")
        recs[f.name] = arr
    return recs


class MessageBlock:
    """Records of one channel, written in order by ``LogWriter.write_block`` (``pos``: the next
    one to write). ``data``: the CDR data of each message, as a structured array of the topic's
    layout or as rows of octets. The records are made whole here, numbered from ``seq0`` on (the
    channel's next sequence number), so that writing a run of them is slicing octets and lists;
    ``renumber`` makes them again when other messages of the channel came between."""

    __slots__ = (
        "channel",
        "increasing",
        "log_times",
        "pos",
        "raw",
        "records",
        "seq0",
        "size",
        "times",
        "topic",
    )

    def __init__(self, topic: str, channel: int, seq0: int, times_ns: np.ndarray, data: np.ndarray):
        n = len(times_ns)
        if len(data) != n:
            raise ValueError(f"{topic}: {len(data)} messages of data for {n} log times")
        size = data.dtype.itemsize if data.ndim == 1 else data.shape[1] * data.dtype.itemsize
        recs = np.empty(n, dtype=record_dtype(size))
        recs["op"] = 5  # Opcode.MESSAGE
        recs["length"] = 22 + size  # the record's content after opcode and length
        recs["channel"] = channel
        recs["log_time"] = times_ns
        recs["publish_time"] = times_ns
        recs["data"] = np.ascontiguousarray(data).view(np.dtype((np.void, size))).reshape(n)
        self.topic = topic
        self.channel = channel
        self.log_times = times_ns
        self.times: list[int] = times_ns.tolist()
        self.increasing = bool(n < 2 or np.all(times_ns[1:] >= times_ns[:-1]))
        self.records = recs
        self.size = recs.dtype.itemsize
        self.pos = 0
        self.renumber(seq0)

    def renumber(self, seq0: int) -> None:
        """Sequence numbers from ``seq0`` on for the records from ``pos`` on."""
        rest = self.records[self.pos :]
        rest["seq"] = np.arange(seq0, seq0 + len(rest), dtype=np.int64) & 0xFFFFFFFF
        self.seq0 = seq0 - self.pos
        self.raw = self.records.tobytes()

    def __len__(self) -> int:
        return len(self.times)
