"""The capture upload on a link that loses chunks (pmsm_hil/protocol/session.py read_capture):
what arrives is kept, lost chunks are listed, a link that carries nothing is given up on after a
few chunks instead of being waited out, and the wait adapts to the link's round trip."""

from __future__ import annotations

import time
from types import SimpleNamespace

import pytest

from pmsm_hil.protocol import generated as gen
from pmsm_hil.protocol.session import Session

PER_CHUNK = next(f.count for f in gen.BY_NAME["capture_chunk"].fields if f.name == "i_a_a")


class ChunkLink:
    """Answers capture_read with a chunk after `delay_s`, unless `lose(offset, attempt)`."""

    def __init__(self, count: int, lose, delay_s: float = 0.001, corrupt=None):
        self.count, self.lose, self.delay_s = count, lose, delay_s
        self.corrupt = corrupt or (lambda off: False)  # answers with an impossible n_valid
        self.decoder = SimpleNamespace()
        self.pending: list[tuple[float, int]] = []
        self.asked: dict[int, int] = {}
        self.outstanding = 0  # requests not answered yet (lost ones stay counted)
        self.most_outstanding = 0

    def send(self, name: str, seq: int, **fields) -> None:
        assert name == "capture_read"
        off = fields["offset"]
        n = self.asked[off] = self.asked.get(off, 0) + 1
        self.outstanding += 1
        self.most_outstanding = max(self.most_outstanding, self.outstanding)
        if not self.lose(off, n):
            self.pending.append((time.monotonic() + self.delay_s, off))

    def poll(self, timeout_s: float) -> list:
        end = time.monotonic() + timeout_s
        while True:
            now = time.monotonic()
            due = [p for p in self.pending if p[0] <= now]
            if due or now >= end:
                break
            time.sleep(0.0005)
        self.pending = [p for p in self.pending if p not in due]
        self.outstanding -= len(due)
        return [
            SimpleNamespace(
                name="capture_chunk",
                fields={
                    "offset": off,
                    "n_valid": PER_CHUNK + 1
                    if self.corrupt(off)
                    else max(0, min(PER_CHUNK, self.count - off)),
                },
            )
            for _t, off in due
        ]


@pytest.mark.parametrize("window", [1, 4])
def test_lost_chunks_are_retried_listed_and_the_rest_kept(window):
    count = 8 * PER_CHUNK
    link = ChunkLink(count, lambda off, n: off == 2 * PER_CHUNK or (off == PER_CHUNK and n == 1))
    s = Session(link)
    chunks = s.read_capture(count, window=window)
    assert [c["offset"] for c in chunks] == [k * PER_CHUNK for k in range(8) if k != 2]
    assert s.capture_missing == [2 * PER_CHUNK] and not s.capture_abandoned
    assert link.asked[PER_CHUNK] == 2 and link.asked[2 * PER_CHUNK] == 3


@pytest.mark.parametrize("window", [1, 4])
def test_a_link_that_carries_nothing_is_given_up_on(window):
    count = 16 * PER_CHUNK
    s = Session(ChunkLink(count, lambda off, n: True))
    t0 = time.monotonic()
    chunks = s.read_capture(count, timeout_s=0.05, give_up_after=4, window=window)
    assert chunks == [] and s.capture_abandoned
    assert s.capture_missing == [k * PER_CHUNK for k in range(16)]
    assert time.monotonic() - t0 < 4 * 3 * 0.05 + 0.5  # four chunks waited out, not sixteen


def test_the_wait_adapts_to_a_fast_link():
    """Round trips of 1 ms: after two chunks a lost one costs 50 ms, not the 2 s timeout."""
    count = 6 * PER_CHUNK
    s = Session(ChunkLink(count, lambda off, n: off == 4 * PER_CHUNK and n == 1))
    t0 = time.monotonic()
    chunks = s.read_capture(count, timeout_s=2.0)
    assert len(chunks) == 6 and s.capture_missing == []
    assert time.monotonic() - t0 < 1.0


def test_a_window_of_chunks_is_asked_for_at_once_and_comes_back_in_order():
    """Up to `window` requests are out before an answer is waited for (one round trip per window
    instead of per chunk); the chunks come back sorted, whatever order they arrive in."""
    count = 20 * PER_CHUNK
    link = ChunkLink(count, lambda off, n: off == 5 * PER_CHUNK and n == 1, delay_s=0.002)
    s = Session(link)
    chunks = s.read_capture(count, window=4)
    assert [c["offset"] for c in chunks] == [k * PER_CHUNK for k in range(20)]
    assert s.capture_missing == [] and link.asked[5 * PER_CHUNK] == 2
    assert link.most_outstanding == 4
    one = ChunkLink(count, lambda off, n: False)
    Session(one).read_capture(count, window=1)
    assert one.most_outstanding == 1


def test_a_chunk_of_no_samples_ends_the_upload_there():
    """The device holds fewer samples than the count said: what it has is kept, nothing beyond
    is asked for again or listed as missing."""
    link = ChunkLink(5 * PER_CHUNK - 3, lambda off, n: False)
    s = Session(link)
    chunks = s.read_capture(12 * PER_CHUNK, window=4)
    assert [c["offset"] for c in chunks] == [k * PER_CHUNK for k in range(5)]
    assert chunks[-1]["n_valid"] == PER_CHUNK - 3
    assert s.capture_missing == [] and not s.capture_abandoned
    assert max(link.asked.values()) == 1


def test_the_window_follows_the_device_and_the_link():
    from pmsm_hil.protocol.can_link import CanLink
    from pmsm_hil.protocol.session import Identity

    s = Session(ChunkLink(8, lambda off, n: False))
    assert s.capture_window() == 1  # no identity yet: one at a time
    s.identity = Identity(1, 0, "1.0.0", "sim", tx_buf_octets=1024, capture_len=1024)
    assert s.capture_window() == 4  # half of 1024 octets holds four chunk frames
    s.identity = Identity(1, 0, "1.0.0", "sim", tx_buf_octets=100, capture_len=1024)
    assert s.capture_window() == 1
    assert CanLink.capture_window == 2


@pytest.mark.parametrize("window", [1, 4])
def test_chunks_that_keep_coming_back_corrupt_count_as_missed_in_a_row(window):
    """A chunk refused as corrupt on every try is missing, and such chunks in a row give the
    upload up as lost ones do."""
    count = 12 * PER_CHUNK
    link = ChunkLink(count, lambda off, n: False, corrupt=lambda off: off >= 2 * PER_CHUNK)
    s = Session(link)
    chunks = s.read_capture(count, window=window, give_up_after=4)
    assert [c["offset"] for c in chunks] == [0, PER_CHUNK]
    assert s.capture_abandoned and s.capture_rejected >= 4 * 3
    assert s.capture_missing == [k * PER_CHUNK for k in range(2, 12)]
