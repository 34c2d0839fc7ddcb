"""Messages written as blocks (LogWriter.message_block / write_block, the run's recorder's path):
the file, and the journal of a writer killed midway, are octet for octet those of the same
messages written one ``write`` at a time, whatever the runs, the chunk bounds and the messages of
other topics or of the same topic in between."""

from __future__ import annotations

import random
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pmsm_hil.log.blocks import cdr_from_columns
from pmsm_hil.log.journal import journal_path
from pmsm_hil.log.reader import read_log, rewrite_log
from pmsm_hil.log.schemas import TOPICS, codec_for
from pmsm_hil.log.writer import LogWriter

TEL = "/pmsm/telemetry"


def _columns(times: list[float], rnd: random.Random) -> dict[str, np.ndarray]:
    cols = {"t_s": np.array(times)}
    for n in ("speed_rpm", "i_d_a", "i_q_a", "u_q_v"):
        cols[n] = np.array([rnd.uniform(-100, 100) for _ in times])
    return cols


def _write_both(tmp_path, times, runs, between, kill=False, **kw):
    """The same messages into a.mcap one write each and into b.mcap as one block written in
    ``runs`` (lengths), with ``between[k]`` ("event" or "tel") written after run k; returns the
    two paths (with kill: not closed, files as a SIGKILL would leave them, journals beside)."""
    rnd = random.Random(len(times))
    cols = _columns(times, rnd)
    rows = [{k: float(v[i]) for k, v in cols.items() if k != "t_s"} for i in range(len(times))]
    paths = []
    for name in ("a", "b"):
        path = tmp_path / f"{name}.mcap"
        w = LogWriter(path, {"run": {"x": "1"}}, journal=True, **kw)
        if name == "b":
            data = cdr_from_columns(TEL, codec_for(TOPICS[TEL]), cols, len(times))
            block = w.message_block(TEL, cols["t_s"], data)
        at = 0
        for k, n in enumerate(runs):
            if name == "a":
                for i in range(at, at + n):
                    w.write(TEL, times[i], rows[i])
            else:
                w.write_block(block, at + n)
            at += n
            extra = between.get(k)
            if extra == "event":
                w.write("/pmsm/events", times[at - 1], {"kind": "host", "text": f"after {k}"})
            elif extra == "tel":  # the same topic outside the block: its sequence goes on
                w.write(TEL, times[at - 1], {"speed_rpm": -1.0})
            w.flush_batch()
        if kill:
            killed = tmp_path / f"{name}-killed.mcap"
            shutil.copyfile(path, killed)
            shutil.copyfile(journal_path(path), journal_path(killed))
            paths.append(killed)
        else:
            w.close()
            paths.append(path)
    return paths


@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(1, 400),
    seed=st.integers(0, 10_000),
    chunk_size=st.sampled_from([700, 5000, 1 << 20]),
    span_s=st.sampled_from([0.003, 0.05, 1.0]),
    backwards=st.booleans(),
)
def test_blocks_write_the_octets_of_single_writes(
    tmp_path_factory, n, seed, chunk_size, span_s, backwards
):
    rnd = random.Random(seed)
    t, times = 0.0, []
    for _ in range(n):
        t += rnd.choice([50e-6, 500e-6, 2e-3])
        if backwards and rnd.random() < 0.05:
            t = max(0.0, t - 0.01)  # a device time that goes back (a reset, a late frame)
        times.append(round(t, 9))
    runs, left = [], n
    while left:
        runs.append(min(left, rnd.randint(1, 60)))
        left -= runs[-1]
    between = {k: rnd.choice(["event", "tel", None]) for k in range(len(runs))}
    tmp = tmp_path_factory.mktemp("blocks")
    a, b = _write_both(tmp, times, runs, between, chunk_size=chunk_size, chunk_span_s=span_s)
    assert a.read_bytes() == b.read_bytes()


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    chunk_size=st.sampled_from([700, 5000, 1 << 20]),
    span_s=st.sampled_from([0.003, 0.05, 1.0]),
)
def test_runs_of_several_blocks_at_once_are_the_octets_of_single_writes(
    tmp_path_factory, seed, chunk_size, span_s
):
    """A receive batch's runs (the recorder's path): two blocks of the telemetry topic, their
    runs interleaved, written by one ``write_runs`` call per group of runs, give the file (and
    the journal) of the same messages written one ``write`` at a time in the same order."""
    rnd = random.Random(seed)
    n = rnd.randint(2, 300)
    times = [round(k * 5e-4, 9) for k in range(n)]
    cols = _columns(times, rnd)
    rows = [{k: float(v[i]) for k, v in cols.items() if k != "t_s"} for i in range(n)]
    owner = [rnd.random() < 0.7 for _ in range(n)]  # message i in block 0 (else block 1)
    order = [[i for i in range(n) if owner[i] == flag] for flag in (True, False)]
    tmp = tmp_path_factory.mktemp("runs")
    kw = {"chunk_size": chunk_size, "chunk_span_s": span_s, "journal": True}
    with LogWriter(tmp / "a.mcap", {"run": {"x": "1"}}, **kw) as w:
        for i in range(n):
            w.write(TEL, times[i], rows[i])
    with LogWriter(tmp / "b.mcap", {"run": {"x": "1"}}, **kw) as w:
        blocks = []
        for idx in order:  # (a block of no message is never made: it has no run)
            sub = {k: v[idx] for k, v in cols.items()}
            data = cdr_from_columns(TEL, codec_for(TOPICS[TEL]), sub, len(idx)) if idx else None
            blocks.append(w.message_block(TEL, sub["t_s"], data) if idx else None)
        runs, done, i = [], [0, 0], 0
        while i < n:  # the runs of consecutive messages of one block, in message order
            j = i
            while j < n and owner[j] == owner[i]:
                j += 1
            b = 0 if owner[i] else 1
            done[b] += j - i
            runs.append((blocks[b], done[b]))
            i = j
            if rnd.random() < 0.3:  # a group ends (a frame that needs its handler came)
                w.write_runs(runs)
                runs = []
        w.write_runs(runs)
    assert (tmp / "a.mcap").read_bytes() == (tmp / "b.mcap").read_bytes()


def test_a_killed_writer_leaves_the_same_log_and_journal(tmp_path):
    times = [k * 1e-3 for k in range(3000)]
    runs = [7, 1, 300, 2000, 692]
    a, b = _write_both(tmp_path, times, runs, {1: "event", 2: "tel"}, kill=True, chunk_span_s=0.25)
    assert a.read_bytes() == b.read_bytes()
    assert Path(journal_path(a)).read_bytes() == Path(journal_path(b)).read_bytes()
    rewrite_log(b, tmp_path / "recovered.mcap")  # `log recover`: the chunks and the journal
    assert read_log(tmp_path / "recovered.mcap").counts[TEL] == 3001


def test_bad_times_and_layouts_are_refused_with_the_topic(tmp_path):
    with LogWriter(tmp_path / "x.mcap") as w:
        codec = codec_for(TOPICS[TEL])
        data = cdr_from_columns(TEL, codec, {"t_s": np.zeros(3)}, 3)
        for bad in (np.array([0.0, np.nan, 1.0]), np.array([0.0, -1e-3, 1.0])):
            with pytest.raises(ValueError, match=r"/pmsm/telemetry: t_s = .* not a device time"):
                w.message_block(TEL, bad, data)
        with pytest.raises(ValueError, match="not the topic's fixed layout"):
            w.message_block(TEL, np.zeros(3), np.zeros((3, 8), np.uint8))
        with pytest.raises(ValueError, match="2 messages of data for 3 log times"):
            w.message_block(TEL, np.zeros(3), data[:2].view(np.uint8).reshape(2, -1))
        with pytest.raises(ValueError, match="values for 3 rows"):
            cdr_from_columns(TEL, codec, {"t_s": np.zeros(3), "i_d_a": np.zeros(2)}, 3)
    assert read_log(tmp_path / "x.mcap").counts.get(TEL, 0) == 0


PARAMS = "/pmsm/params"


@settings(max_examples=40, deadline=None)
@given(
    names=st.lists(st.text(max_size=20), min_size=1, max_size=3),
    values=st.lists(
        st.tuples(st.floats(0, 1e3), st.floats(allow_nan=False), st.booleans()),
        min_size=1,
        max_size=30,
    ),
)
def test_a_topic_with_strings_has_a_block_layout_per_string_value(tmp_path_factory, names, values):
    """/pmsm/params (its estimator a string): blocks made from the layout that ``fixed_layout``
    gives for each estimator's name, filled from its template, are the octets of ``write``."""
    tmp = tmp_path_factory.mktemp("p")
    rows = [
        {
            "estimator": names[k % len(names)],
            "l_d_h": x,
            "l_q_h": -x,
            "psi_f_wb": 0.25,
            "r_s_ohm": x / 3,
            "excited": flag,
            "converged": not flag,
            "feeds_predictor": flag,
        }
        for k, (_t, x, flag) in enumerate(values)
    ]
    times = sorted(t for t, _x, _f in values)
    with LogWriter(tmp / "a.mcap") as w:
        for t, row in zip(times, rows, strict=True):
            w.write(PARAMS, t, row)
    with LogWriter(tmp / "b.mcap") as w:
        assert w.fixed_layout(PARAMS) is None  # a string's value is needed
        for t, row in zip(times, rows, strict=True):  # one block per message: any order of names
            layout = w.fixed_layout(PARAMS, {"estimator": row["estimator"]})
            assert layout is not None and layout.template is not None
            assert "estimator" not in layout.names
            raw = np.empty((1, layout.dtype.itemsize), np.uint8)
            raw[:] = np.frombuffer(layout.template, np.uint8)
            data = raw.view(layout.dtype).reshape(1)
            data["t_s"] = t
            for n in layout.names[1:]:
                data[n] = row[n]
            w.write_block(w.message_block(PARAMS, [t], data))
    assert (tmp / "a.mcap").read_bytes() == (tmp / "b.mcap").read_bytes()


def test_a_layout_with_strings_is_one_the_writer_gave(tmp_path):
    with LogWriter(tmp_path / "x.mcap") as w:
        layout = w.fixed_layout(PARAMS, {"estimator": "rls"})
        assert layout is not None
        other = np.dtype({"names": ["t_s"], "formats": ["<f8"], "offsets": [4], "itemsize": 55})
        with pytest.raises(ValueError, match=r"/pmsm/params: data of .* not the topic's fixed"):
            w.message_block(PARAMS, [0.0], np.zeros(1, other))
        w.message_block(PARAMS, [0.0], np.zeros(1, layout.dtype))  # the one it gave: taken
