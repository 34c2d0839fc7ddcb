"""The log's journal (pmsm_hil/log/journal.py): a writer killed at any point has on disk, in its
chunks and its journal, every message added before its last flush_batch(), once each; rewrite_log
(`pmsm-hil log recover`) makes one finalised file of them for the generic `mcap` reader."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from mcap.reader import make_reader

from pmsm_hil.log.journal import journal_path, read_journal
from pmsm_hil.log.reader import read_log, rewrite_log
from pmsm_hil.log.writer import LogWriter

TS_S = 50e-6


def _row(k: int) -> dict:
    return {"speed_ref_rpm": float(k), "speed_rpm": float(k) / 2, "i_q_a": 0.001 * k}


def _snapshot(src: Path, dst: Path) -> Path:
    """The log and its journal as a SIGKILL at this moment would leave them (both go to the OS
    with plain writes, so the files' contents are what the kill leaves)."""
    shutil.copyfile(src, dst)
    shutil.copyfile(journal_path(src), journal_path(dst))
    return dst


def _times(path: Path, topic: str = "/pmsm/telemetry") -> list[int]:
    with open(path, "rb") as f:
        return [m.log_time for _, c, m in make_reader(f).iter_messages() if c.topic == topic]


@pytest.mark.parametrize("chunk_size", [1 << 20, 3000])
def test_every_batch_is_recovered_at_any_kill(tmp_path, chunk_size):
    """Batches of 7 messages; after each batch's flush_batch the files are taken as a kill would
    leave them, recovered, and read with the generic reader: exactly the messages so far, in order
    (small chunks: the journal restarts many times; large: it holds everything)."""
    path = tmp_path / "run.mcap"
    w = LogWriter(path, chunk_size=chunk_size, chunk_span_s=0.01, journal=True)
    k = 0
    for batch in range(40):
        for _ in range(7):
            w.write("/pmsm/telemetry", k * TS_S, _row(k))
            k += 1
        if batch % 10 == 3:
            w.write("/pmsm/events", k * TS_S, {"kind": "host", "text": f"batch {batch}"})
        w.flush_batch()
        if batch % 6 == 5:
            killed = _snapshot(path, tmp_path / f"killed{batch}.mcap")
            fixed = tmp_path / f"fixed{batch}.mcap"
            rewrite_log(killed, fixed)
            assert _times(fixed) == [round(i * TS_S * 1e9) for i in range(k)]
            assert len(_times(fixed, "/pmsm/events")) == (batch + 7) // 10
    w.close()
    assert not os.path.exists(journal_path(path))  # a finalised log needs no journal
    assert _times(path) == [round(i * TS_S * 1e9) for i in range(k)]


def test_a_kill_between_the_chunk_and_the_journals_restart_counts_nothing_twice(
    tmp_path, monkeypatch
):
    """The chunk went out, the journal had not restarted yet: its first messages are in the
    chunk too, and read_journal leaves them out (by the journal's base count)."""
    path = tmp_path / "run.mcap"
    w = LogWriter(path, chunk_span_s=1.0, journal=True)
    for k in range(30):
        w.write("/pmsm/telemetry", k * 0.01, _row(k))
    w.flush_batch()
    before = Path(journal_path(path)).read_bytes()
    w.flush()  # the chunk goes out; the journal restarts
    killed = tmp_path / "killed.mcap"
    shutil.copyfile(path, killed)
    Path(journal_path(killed)).write_bytes(before)  # as if killed before the restart
    log = read_log(killed)
    assert sum(log.counts.values()) == 30
    assert read_journal(killed, 30) == []
    rewrite_log(killed, tmp_path / "fixed.mcap")
    assert len(_times(tmp_path / "fixed.mcap")) == 30
    w.close()
