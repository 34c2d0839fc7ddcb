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


def _journal_log(tmp_path: Path) -> Path:
    """A finalised log written with a journal (its journal removed at the close), 40 chunks."""
    path = tmp_path / "run.mcap"
    w = LogWriter(path, chunk_size=3000, chunk_span_s=0.01, journal=True)
    for k in range(2000):
        w.write("/pmsm/telemetry", k * TS_S, _row(k))
        if k % 50 == 49:
            w.flush_batch()
    w.close()
    return path


def test_recover_of_a_cut_copy_without_its_journal_says_what_is_lost(tmp_path, capsys):
    """A log copied without its journal (cut with `head -c`): everything after its last complete
    chunk is gone, and the recovery says so with the device time it covers; "none lost" would
    be wrong."""
    from pmsm_hil.cli.main import main

    src = _journal_log(tmp_path)
    half = tmp_path / "half.mcap"
    half.write_bytes(src.read_bytes()[: src.stat().st_size // 2])
    assert main(["log", "recover", str(half)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    t = _times(tmp_path / "half.recovered.mcap")
    assert 0 < len(t) < 2000
    assert (
        f"lost: everything after the last complete chunk (t = {t[-1] / 1e9:.4f} s): the log was "
        "written with a journal" in out
    )
    assert f"{journal_path(half)} is not beside it" in out
    assert f"the recovered part covers t = 0.0000 .. {t[-1] / 1e9:.4f} s of device time" in out
    assert "none of the device's messages" not in out


def test_recover_of_a_finalised_log_says_nothing_was_missing(tmp_path, capsys):
    from pmsm_hil.cli.main import main

    done = tmp_path / "done.mcap"
    with LogWriter(done) as w:
        w.write("/pmsm/telemetry", 0.0, _row(0))
    assert main(["log", "recover", str(done)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert f"note: {done} was finalised (its run ended and closed it)" in out
    assert "nothing was missing" in out
    src = _journal_log(tmp_path)
    half = tmp_path / "half.mcap"  # a killed run's log, cut: no such note
    half.write_bytes(src.read_bytes()[: src.stat().st_size // 2])
    assert main(["log", "recover", str(half)]) == 0
    assert "nothing was missing" not in capsys.readouterr().out


def test_recover_of_a_log_without_a_complete_chunk_is_an_error(tmp_path, capsys):
    """300 octets of a log: nothing to recover is an error (exit 2), not an empty "finalised"
    file; one message is "1 message"."""
    from pmsm_hil.cli.main import main

    src = _journal_log(tmp_path)
    tiny = tmp_path / "tiny.mcap"
    tiny.write_bytes(src.read_bytes()[:300])
    assert main(["log", "recover", str(tiny)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"{tiny}: nothing to recover: not one complete chunk of messages (300 octets" in err
    assert "nothing written" in err and "Traceback" not in err
    assert not (tmp_path / "tiny.recovered.mcap").exists()
    one = tmp_path / "one.mcap"
    with LogWriter(one) as w:
        w.write("/pmsm/telemetry", 0.0, _row(0))
    assert main(["log", "recover", str(one), "-o", str(tmp_path / "one-r.mcap")]) == 0
    out = capsys.readouterr().out
    assert "1 message in 1 topic recovered" in out and "/pmsm/telemetry: 1 message," in out
    assert "1 messages" not in out


def _killed_run(tmp_path: Path) -> Path:
    """A log of 30 telemetry messages as a killed writer left it (the last of them in the journal
    only): tmp_path/killed.mcap beside its journal."""
    path = tmp_path / "run.mcap"
    w = LogWriter(path, chunk_span_s=1.0, journal=True)
    for k in range(30):
        w.write("/pmsm/telemetry", k * 0.01, _row(k))
    w.flush_batch()
    killed = _snapshot(path, tmp_path / "killed.mcap")
    w.close()
    return killed


def test_recover_does_not_write_over_the_logs_own_journal(tmp_path, capsys):
    """`-o LOG.journal` would read the journal while writing over it: the messages received after
    the last chunk would be lost. Refused (exit 2), like `-o LOG`; both files stay as they were."""
    from pmsm_hil.cli.main import main

    killed = _killed_run(tmp_path)
    journal = Path(journal_path(killed))
    before = journal.read_bytes(), killed.read_bytes()
    assert main(["log", "recover", str(killed), "-o", str(journal)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"-o {journal}: " in err and "journal" in err
    assert (journal.read_bytes(), killed.read_bytes()) == before
    assert main(["log", "recover", str(killed)]) == 0
    assert len(_times(tmp_path / "killed.recovered.mcap")) == 30


def test_recover_keeps_a_file_already_at_its_output_unless_told(tmp_path, capsys):
    """`-o` naming another run's log (or an earlier recovery at the default path) is refused
    with what to do, the file untouched; `--overwrite` replaces it."""
    from pmsm_hil.cli.main import main

    killed = _killed_run(tmp_path)
    other = tmp_path / "other.mcap"
    other.write_bytes(b"another run's log")
    assert main(["log", "recover", str(killed), "-o", str(other)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"-o {other}: a file is there already; --overwrite replaces it" in err
    assert other.read_bytes() == b"another run's log"
    assert main(["log", "recover", str(killed), "-o", str(other), "--overwrite"]) == 0
    assert len(_times(other)) == 30
