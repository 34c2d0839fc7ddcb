"""Topic-selective reading: read_log(path, topics=...) gives the same columns as the full read,
opens only the chunks that hold the asked topics, and the vectorised decode of layouts with strings
equals the per-message codec."""

from __future__ import annotations

import numpy as np
import pytest
from test_log import ATTACH, META, sample_rows, write_rows

from pmsm_hil.log.columns import decode_columns
from pmsm_hil.log.reader import read_log
from pmsm_hil.log.schemas import CDR_LE_HEADER, TOPICS, codec_for
from pmsm_hil.log.writer import LogWriter


def assert_same(a: dict, b: dict) -> None:
    assert list(a) == list(b)
    for k, va in a.items():
        assert va.dtype == b[k].dtype, k
        if va.dtype == object:
            assert list(va) == list(b[k]), k
        else:
            np.testing.assert_array_equal(va, b[k], err_msg=k)


@pytest.fixture()
def mixed_log(tmp_path):
    """Every topic, interleaved over many small chunks."""
    path = tmp_path / "mixed.mcap"
    rows = {t: sample_rows(t, 3000 if t == "/pmsm/telemetry" else 400) for t in TOPICS}
    with LogWriter(path, META, ATTACH, chunk_size=16 * 1024) as w:
        for i in range(10):
            for t, rs in rows.items():
                k = len(rs) // 10
                write_rows(w, t, rs[i * k : (i + 1) * k])
    return path


def test_selected_topics_and_fields_equal_the_full_read(mixed_log):
    full = read_log(mixed_log)
    for topic in TOPICS:
        one = read_log(mixed_log, topics=[topic])
        assert_same(one.topic(topic), full.topic(topic))
        np.testing.assert_array_equal(one.log_times_ns(topic), full.log_times_ns(topic))
        assert one.counts == full.counts and one.topics == full.topics
        assert one.metadata == full.metadata and len(one.attachments) == len(ATTACH)
    fields = ("t_s", "speed_rpm", "i_q_a")
    part = read_log(mixed_log, topics={"/pmsm/telemetry": fields, "/pmsm/params": None})
    tel = part.topic("/pmsm/telemetry")
    assert list(tel) == list(fields)
    assert_same(tel, {k: full.topic("/pmsm/telemetry")[k] for k in fields})
    assert_same(part.topic("/pmsm/params"), full.topic("/pmsm/params"))
    # a topic not asked for is read when used, the same as in the full read
    assert_same(part.topic("/pmsm/events"), full.topic("/pmsm/events"))


def test_an_unfinalised_log_reads_the_same_with_topics(mixed_log, tmp_path):
    cut = tmp_path / "cut.mcap"
    data = mixed_log.read_bytes()
    cut.write_bytes(data[: len(data) * 2 // 3])
    full = read_log(cut)
    assert not full.finalised
    for topic in ("/pmsm/telemetry", "/pmsm/status"):
        one = read_log(cut, topics=[topic])
        assert len(one.topic(topic)["t_s"]) > 0
        assert_same(one.topic(topic), full.topic(topic))


def test_only_the_chunks_holding_the_asked_topics_are_opened(tmp_path):
    """A log with one topic per chunk: reading one topic decompresses its chunks only."""
    path = tmp_path / "topics.mcap"
    names = ["/pmsm/telemetry", "/pmsm/status", "/sim/truth", "/pmsm/params"]
    rows = {t: sample_rows(t, 50, t0=10.0 * i) for i, t in enumerate(names)}
    per_topic = 3
    with LogWriter(path, META, ATTACH) as w:
        for t in names:
            for j in range(per_topic):
                write_rows(w, t, rows[t][j * 10 : (j + 1) * 10])
                w.flush()  # one chunk per call
    full = read_log(path)
    assert full.chunks_read == len(names) * per_topic and full.chunks_skipped == 0
    one = read_log(path, topics=["/sim/truth"])
    assert one.chunks_read == per_topic
    assert one.chunks_skipped == (len(names) - 1) * per_topic
    assert_same(one.topic("/sim/truth"), full.topic("/sim/truth"))
    assert one.counts == full.counts == {t: 10 * per_topic for t in names}


def test_vectorised_decode_of_strings_equals_the_codec():
    codec = codec_for("/pmsm/events")
    rows = sample_rows("/pmsm/events", 500, seed=3)
    datas = [codec.encode([r[n] for n in codec.names]) for r in rows]
    gap = b"\x07" * 5  # other records between the messages
    buf = b"".join(gap + d for d in datas)
    sizes = np.array([len(d) for d in datas])
    starts = np.cumsum(sizes + len(gap)) - sizes
    cols = decode_columns(codec, np.frombuffer(buf, np.uint8), starts, sizes)
    want = codec.columns_from_rows([codec.decode(d) for d in datas])
    assert_same(cols, want)
    assert set(cols["text"]) >= {"", "\u00b5-Grad \u2713"}
    # a message cut short is an error, not garbage
    bad = datas[0][: len(datas[0]) - 3]
    with pytest.raises(ValueError):
        decode_columns(codec, np.frombuffer(bad, np.uint8), [0], [len(bad)])
    assert datas[0][:4] == CDR_LE_HEADER


def _chunk_threads() -> list:
    import threading

    return [t for t in threading.enumerate() if t.name.startswith("mcap-chunks")]


@pytest.mark.parametrize(("finalised", "pread"), [(True, True), (False, True), (True, False)])
def test_chunks_read_ahead_give_what_one_chunk_at_a_time_gives(
    mixed_log, tmp_path, monkeypatch, finalised, pread
):
    """Chunks are read and decompressed on a second thread ahead of the decoding, and decoded
    several at a time: the columns, times, counts and problems are those of decoding each chunk
    as it is met, in a finalised log and in one cut short, with or without os.pread, and no
    thread outlives the read."""
    from pmsm_hil.log import parse

    path = mixed_log
    if not finalised:
        path = tmp_path / "cut.mcap"
        data = mixed_log.read_bytes()
        path.write_bytes(data[: len(data) * 2 // 3])
    if not pread:  # a platform without os.pread (Windows): the thread's own file handle
        monkeypatch.delattr(parse.os, "pread")
    groups = []
    merged = parse._Parser._decode_merged

    def spy(self, group):
        groups.append(len(group))
        merged(self, group)

    monkeypatch.setattr(parse._Parser, "_decode_merged", spy)
    ahead = read_log(path)
    assert len(groups) > 1 and max(groups) == parse._MERGE
    monkeypatch.setattr(parse, "_AHEAD", 0)
    monkeypatch.setattr(parse, "_MERGE", 1)
    one = read_log(path)
    assert ahead.chunks_read == one.chunks_read > 10
    assert ahead.finalised == one.finalised == finalised
    assert ahead.counts == one.counts and ahead.problems == one.problems
    for t in one.topics:
        assert_same(ahead.topic(t), one.topic(t))
        np.testing.assert_array_equal(ahead.log_times_ns(t), one.log_times_ns(t))
    assert not _chunk_threads()


def test_a_group_whose_indexes_do_not_fit_is_decoded_chunk_by_chunk(mixed_log, monkeypatch):
    """When the joined chunks' message indexes do not account for their records (a damaged or
    partial index), each chunk of the group is decoded on its own: the same columns."""
    from pmsm_hil.log import parse

    full = read_log(mixed_log)
    calls = []
    original = parse._Parser._chunk_indexed

    def refuse_groups(self, records, indexes):
        calls.append(len(records))
        if len(records) > 3 * 16 * 1024:  # a group of chunks (16 KiB each), not one chunk
            return False
        return original(self, records, indexes)

    monkeypatch.setattr(parse._Parser, "_chunk_indexed", refuse_groups)
    again = read_log(mixed_log)
    assert max(calls) > 3 * 16 * 1024 and min(calls) <= 16 * 1024 + 4096
    assert again.chunks_read == full.chunks_read and again.counts == full.counts
    for t in full.topics:
        assert_same(again.topic(t), full.topic(t))
        np.testing.assert_array_equal(again.log_times_ns(t), full.log_times_ns(t))


def test_a_read_that_fails_midway_leaves_no_read_ahead_behind(mixed_log, monkeypatch):
    from pmsm_hil.log import parse

    seen = []
    original = parse._Parser._chunk_indexed

    def failing(self, records, indexes):
        seen.append(1)
        if len(seen) == 2:
            raise RuntimeError("decoding failed on the second group of chunks")
        return original(self, records, indexes)

    monkeypatch.setattr(parse._Parser, "_chunk_indexed", failing)
    with pytest.raises(RuntimeError, match="second group"):
        read_log(mixed_log)
    assert len(seen) == 2 and not _chunk_threads()


def test_the_read_ahead_is_bounded_in_octets(mixed_log, monkeypatch):
    """With chunks larger than the read-ahead's octet bound, at most one is in flight at a time:
    the memory held stays that of the chunk being decoded whatever the file's chunk size."""
    from pmsm_hil.log import parse

    in_flight = []
    original = parse._Parser._drain

    def watched(self, keep):
        original(self, keep)
        in_flight.append(len(self._ahead))

    monkeypatch.setattr(parse._Parser, "_drain", watched)
    full = read_log(mixed_log)
    assert max(in_flight) == parse._AHEAD  # small chunks: four ahead
    in_flight.clear()
    monkeypatch.setattr(parse, "_AHEAD_OCTETS", 1)
    bounded = read_log(mixed_log)
    assert max(in_flight) == 0
    assert bounded.counts == full.counts
    for t in full.topics:
        assert_same(bounded.topic(t), full.topic(t))


@pytest.mark.parametrize("finalised", [True, False])
def test_a_message_that_is_not_little_endian_cdr_is_its_topics_error(tmp_path, finalised):
    """A fixed-layout message with another CDR header: reading its topic names the topic and the
    problem, in a finalised file and in one without its summary; the other topics read as
    written."""
    codec = codec_for("/pmsm/telemetry")
    rows = sample_rows("/pmsm/telemetry", 60)
    status = sample_rows("/pmsm/status", 10)
    path = tmp_path / "be.mcap"
    w = LogWriter(path, META, ATTACH)
    write_rows(w, "/pmsm/status", status)
    for i, r in enumerate(rows):
        data = codec.encode([r[k] for k in codec.names])
        if i == 30:
            data = b"\x00\x00" + data[2:]  # big-endian CDR
        w.write_encoded("/pmsm/telemetry", round(r["t_s"] * 1e9), data)
    w.flush()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes())  # as a killed writer leaves it: no summary
    w.close()
    log = read_log(path if finalised else cut)
    assert log.finalised == finalised
    with pytest.raises(ValueError, match=r"/pmsm/telemetry: not little-endian CDR data"):
        log.topic("/pmsm/telemetry")
    np.testing.assert_array_equal(
        log.topic("/pmsm/status")["t_s"], np.array([r["t_s"] for r in status])
    )


def test_rewrite_streams_the_log_chunk_by_chunk(mixed_log, tmp_path):
    """rewrite_log writes each chunk's messages as they are read: the rewritten file holds every
    message of a cut-short source (all fields, the same log times, strings included) while the
    log it returns holds only their device times (the memory of a long log's recovery)."""
    from pmsm_hil.log.reader import rewrite_log

    cut = tmp_path / "cut.mcap"
    data = mixed_log.read_bytes()
    cut.write_bytes(data[: len(data) * 3 // 4])
    src = read_log(cut)
    assert not src.finalised and src.chunks_read > 10
    got = rewrite_log(cut, tmp_path / "fixed.mcap")
    fixed = read_log(tmp_path / "fixed.mcap")
    assert fixed.finalised and fixed.counts == src.counts == got.counts
    for t in src.topics:
        assert_same(fixed.topic(t), src.topic(t))
        np.testing.assert_array_equal(fixed.log_times_ns(t), src.log_times_ns(t))
        assert list(got.topic(t)) == ["t_s"]
        np.testing.assert_array_equal(got.topic(t)["t_s"], src.topic(t)["t_s"])


def test_a_field_the_topic_does_not_have_is_named_not_left_out(mixed_log):
    """`topics={topic: fields}` with a misspelt field: a KeyError that names it and the likely
    field, instead of columns without it (and a bare KeyError later, in the user's code)."""
    log = read_log(mixed_log, topics={"/pmsm/telemetry": ("t_s", "speed_rmp")})
    with pytest.raises(KeyError) as e:
        log.topic("/pmsm/telemetry")
    msg = str(e.value)
    assert "/pmsm/telemetry has no field 'speed_rmp'; did you mean 'speed_rpm'?" in msg
    assert "i_q_ref_a" in msg  # the fields there are
    ok = read_log(mixed_log, topics={"/pmsm/telemetry": ("t_s", "speed_rpm")})
    assert list(ok.topic("/pmsm/telemetry")) == ["t_s", "speed_rpm"]
