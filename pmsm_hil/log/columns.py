"""Vectorised CDR decoding of many messages of one flat schema into numpy columns.

The messages lie anywhere in one buffer (a decompressed chunk): ``starts`` are the offsets of their
data (the 4-octet encapsulation header first), ``sizes`` their lengths. Fixed layouts (primitives
only) are gathered row-wise and viewed through the codec's numpy dtype; layouts with strings are
walked field by field with a cursor per message (the CDR alignment of each field depends on the
lengths of the strings before it), every step a numpy operation over all messages at once. Strings
become Python ``str`` objects in object arrays, decoded once per distinct value.

    cols = decode_columns(codec, buf, starts, sizes, names=("t_s", "speed_rpm"))
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from pmsm_hil.log.schemas import PRIMITIVES, Codec

__all__ = ["DecodeError", "decode_columns", "gather", "rows_at"]


class DecodeError(ValueError):
    """Messages that do not fit the schema (too short, not little-endian CDR)."""


def rows_at(buf: np.ndarray, pos: np.ndarray, width: int) -> np.ndarray:
    """(n, width) uint8: the octets buf[pos[i] : pos[i] + width] of each message."""
    if width == 0 or len(buf) < width:
        return np.empty((len(pos), width), np.uint8)
    # one window of `width` octets per position, as a single opaque item: the gather copies each
    # row at once (as a (positions, width) uint8 view it copied octet by octet, twice as slow)
    windows = np.ndarray((len(buf) - width + 1,), np.dtype((np.void, width)), buf, 0, (1,))
    return windows[pos].view(np.uint8).reshape(len(pos), width)


def gather(buf: np.ndarray, starts: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """The octets of the messages at ``starts`` (``sizes`` long), one after the other."""
    total = int(sizes.sum())
    if total == 0:
        return np.empty(0, np.uint8)
    if len(sizes) and (sizes == sizes[0]).all():
        return rows_at(buf, starts, int(sizes[0])).reshape(-1)
    width = int(sizes.max())
    if width <= 2 * int(sizes.min()) and bool(np.all(starts + width <= len(buf))):
        # sizes close to each other (strings of a few lengths): rows as wide as the widest,
        # each cut to its message (no index array per octet)
        return rows_at(buf, starts, width)[np.arange(width) < sizes[:, None]]
    first = np.cumsum(sizes) - sizes  # where each message goes in the output
    return buf[np.repeat(starts - first, sizes) + np.arange(total)]


def _native(dt: str) -> np.dtype:
    return np.dtype(dt).newbyteorder("=")


def decode_columns(
    codec: Codec,
    buf: np.ndarray,
    starts: np.ndarray,
    sizes: np.ndarray,
    names: Iterable[str] | None = None,
    copy: bool = True,
) -> dict[str, np.ndarray]:
    """Columns (only ``names``, default all fields) of the messages at ``starts`` in ``buf``.
    ``copy=False``: the columns of a fixed layout may be strided views of one gathered block
    (the caller copies them where they go)."""
    buf = np.asarray(buf, dtype=np.uint8).reshape(-1)
    starts = np.asarray(starts, dtype=np.int64)
    sizes = np.asarray(sizes, dtype=np.int64)
    want = set(codec.names if names is None else names)
    n = len(starts)
    if n == 0:
        return {k: v for k, v in codec.empty().items() if k in want}
    if starts.min() < 0 or np.any(starts + sizes > len(buf)):
        raise DecodeError(f"{codec.topic.topic}: message data outside the buffer")
    if np.any(sizes < 4):
        raise DecodeError(f"{codec.topic.topic}: messages shorter than the CDR header")
    head = rows_at(buf, starts, 2)
    if np.any(head[:, 0] != 0) or np.any(head[:, 1] != 1):
        raise DecodeError(f"{codec.topic.topic}: not little-endian CDR data")
    if (
        codec.fixed
        and codec.size is not None
        and codec.dtype is not None
        and (sizes == codec.size).all()
    ):
        recs = rows_at(buf, starts, codec.size).view(codec.dtype).reshape(n)
        return {
            f.name: recs[f.name].astype(_native(PRIMITIVES[f.type][2]), copy=copy)
            for f in codec.fields
            if f.name in want
        }
    return _decode_walk(codec, buf, starts + 4, sizes - 4, want)


def _decode_walk(
    codec: Codec, buf: np.ndarray, base: np.ndarray, avail: np.ndarray, want: set
) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    n = len(base)
    off = np.zeros(n, dtype=np.int64)  # CDR offset of each message's cursor

    def take(width: int, what: str) -> np.ndarray:
        if np.any(off + width > avail):
            raise DecodeError(f"{codec.topic.topic}.{what}: messages too short for the schema")
        return rows_at(buf, base + off, width)

    for f in codec.fields:
        if f.type == "string":
            off += (-off) & 3
            length = take(4, f.name).copy().view("<u4").reshape(n).astype(np.int64)
            off += 4
            if np.any(off + length > avail):
                raise DecodeError(f"{codec.topic.topic}.{f.name}: string beyond the message")
            if f.name in want:
                out[f.name] = _strings(buf, base + off, length)
            off += length
            continue
        _, sz, dt, _ = PRIMITIVES[f.type]
        off += (-off) % sz
        raw = take(sz, f.name)
        if f.name in want:
            out[f.name] = raw.copy().view(dt).reshape(n).astype(_native(dt))
        off += sz
    return out


def _strings(buf: np.ndarray, pos: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Object array of str: each string's octets less its terminating NUL, decoded as UTF-8
    once per distinct value."""
    n = len(pos)
    res = np.empty(n, dtype=object)
    text_len = np.maximum(length - 1, 0)
    for w in np.unique(text_len).tolist():
        sel = np.nonzero(text_len == w)[0]
        if w == 0:
            res[sel] = ""
            continue
        raw = np.ascontiguousarray(rows_at(buf, pos[sel], w))
        # rows as one void scalar each: unique without NUL stripping
        keys = raw.view(np.dtype((np.void, w))).reshape(-1)
        uniq, inv = np.unique(keys, return_inverse=True)
        texts = np.empty(len(uniq), dtype=object)
        texts[:] = [bytes(u).decode("utf-8") for u in uniq]
        res[sel] = texts[inv.reshape(-1)]
    return res
