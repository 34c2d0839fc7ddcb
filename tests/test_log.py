"""MCAP log: round trip of every topic, Foxglove/mcap_ros2 compatibility of the CDR, metadata and
attachments, unfinalised (truncated, killed) files, close() safety, write_many, throughput."""

from __future__ import annotations

import io
import math
import os
import random
import signal
import struct
import subprocess
import sys
import textwrap
import zlib
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from mcap_ros2._dynamic import serialize_dynamic
from mcap_ros2.decoder import DecoderFactory

from pmsm_hil.log.reader import LogFormatError, read_log, rewrite_log
from pmsm_hil.log.schemas import TOPICS, codec_for, schema_hash
from pmsm_hil.log.write_support import available_compressions
from pmsm_hil.log.writer import LogWriter

ROOT = Path(__file__).resolve().parents[1]
META = {
    "run": {"profile": "paper-a", "seed": "7", "host_version": "0.1.0"},
    "device": {"fw_version": "0.1.0", "schema_hash": "deadbeef", "proto_version": "1"},
}
ATTACH = [
    ("profile.yaml", "application/yaml", b"name: paper-a\n"),
    ("motor.yaml", "application/yaml", "name: m\nsource: \u00b5H\n".encode()),
]


def random_value(rnd: random.Random, typ: str):
    if typ == "string":
        return rnd.choice(["", "a", "ab", "abc", "running", "nlms_adaline", "\u00b5-Grad \u2713"])
    if typ == "bool":
        return rnd.random() < 0.5
    if typ == "uint8":
        return rnd.randrange(2)
    if typ == "uint16":
        return rnd.randrange(1 << 16)
    if typ == "uint32":
        return rnd.randrange(1 << 32)
    if typ == "int32":
        return rnd.randrange(-(1 << 31), 1 << 31)
    return rnd.uniform(-1e3, 1e3)


def sample_rows(topic: str, n: int, seed: int = 1, t0: float = 0.0, dt: float = 5e-4) -> list[dict]:
    rnd = random.Random(f"{topic}{seed}")
    td = TOPICS[topic]
    return [
        {"t_s": t0 + i * dt, **{f.name: random_value(rnd, f.type) for f in td.fields[1:]}}
        for i in range(n)
    ]


def write_rows(w: LogWriter, topic: str, rows: list[dict]) -> None:
    for r in rows:
        r = dict(r)
        w.write(topic, r.pop("t_s"), r)


def assert_columns_equal(cols: dict, rows: list[dict], topic: str) -> None:
    td = TOPICS[topic]
    assert list(cols) == list(td.names)
    for f in td.fields:
        got = cols[f.name]
        want = [r[f.name] for r in rows]
        assert len(got) == len(want)
        if f.type == "string":
            assert list(got) == want, f.name
        else:
            np.testing.assert_array_equal(
                got, np.array(want, dtype=got.dtype), err_msg=f"{topic}.{f.name}"
            )


@pytest.fixture()
def all_topics_log(tmp_path):
    path = tmp_path / "all.mcap"
    rows = {t: sample_rows(t, 300 if t == "/pmsm/telemetry" else 40) for t in TOPICS}
    with LogWriter(path, META, ATTACH) as w:
        for t, rs in rows.items():
            write_rows(w, t, rs)
    return path, rows


# ----------------------------------------------------------------------------------- contract


def test_cdr_is_byte_identical_to_mcap_ros2_encoder():
    rnd = random.Random(3)
    for topic, td in TOPICS.items():
        enc = serialize_dynamic(td.schema_name, td.msgdef)[td.schema_name]
        codec = codec_for(topic)
        for _ in range(200):
            vals = [random_value(rnd, f.type) for f in td.fields]
            ours = codec.encode(vals)
            assert ours == bytes(enc(dict(zip(td.names, vals, strict=False)))), topic
            assert list(codec.decode(ours)) == vals


def test_schema_names_and_fields():
    assert TOPICS["/pmsm/telemetry"].schema_name == "pmsm_hil/msg/Telemetry"
    assert TOPICS["/pmsm/telemetry"].names == (
        "t_s",
        "speed_ref_rpm",
        "speed_rpm",
        "speed_est_rpm",
        "theta_e_rad",
        "theta_e_est_rad",
        "i_d_a",
        "i_q_a",
        "i_d_ref_a",
        "i_q_ref_a",
        "u_d_v",
        "u_q_v",
        "load_nm",
    )
    assert TOPICS["/pmsm/estimator"].names == (
        "t_s",
        "estimator",
        "locked",
        "in_loop",
        "confidence",
        "theta_err_rad",
        "speed_err_rpm",
        "err_signal",
    )
    assert set(TOPICS) == {
        "/pmsm/telemetry",
        "/pmsm/estimator",
        "/pmsm/params",
        "/pmsm/capture",
        "/pmsm/status",
        "/pmsm/events",
        "/pmsm/commission",
        "/sim/truth",
        "/host/link",
    }
    for td in TOPICS.values():
        assert td.fields[0].name == "t_s" and td.fields[0].type == "float64"
    assert len(schema_hash()) == 16


# ----------------------------------------------------------------------------------- round trip


def test_round_trip_every_topic(all_topics_log):
    path, rows = all_topics_log
    log = read_log(path)
    assert log.finalised and not log.truncated and not log.problems
    assert log.counts == {t: len(r) for t, r in rows.items()}
    for topic, rs in rows.items():
        assert_columns_equal(log.topic(topic), rs, topic)
        np.testing.assert_array_equal(log.log_times_ns(topic), [round(r["t_s"] * 1e9) for r in rs])


def test_mcap_ros2_decoder_gives_the_same_values(all_topics_log):
    path, rows = all_topics_log
    seen = {t: [] for t in TOPICS}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
            assert schema.name == TOPICS[channel.topic].schema_name
            assert message.log_time == message.publish_time
            assert message.log_time == round(decoded.t_s * 1e9)
            seen[channel.topic].append(
                {n: getattr(decoded, n) for n in TOPICS[channel.topic].names}
            )
    for topic, rs in rows.items():
        got = seen[topic]
        assert len(got) == len(rs)
        for a, b in zip(got, rs, strict=False):
            for k, v in b.items():
                assert a[k] == v, (topic, k)


def test_valid_mcap_for_the_reference_readers(all_topics_log):
    path, rows = all_topics_log
    data = path.read_bytes()
    # data-section CRC, chunk CRCs and record framing checked by the stream reader
    n = sum(
        isinstance(r, Message) for r in StreamReader(io.BytesIO(data), validate_crcs=True).records
    )
    assert n == sum(len(r) for r in rows.values())
    # summary: statistics, chunk indexes, log-time ordered iteration
    reader = make_reader(io.BytesIO(data))
    summary = reader.get_summary()
    assert summary.statistics.message_count == n
    assert summary.statistics.channel_message_counts == {
        c.id: len(rows[c.topic]) for c in summary.channels.values()
    }
    times = [m.log_time for _, _, m in reader.iter_messages(log_time_order=True)]
    assert len(times) == n and times == sorted(times)
    # footer summary CRC
    footer_at = len(data) - 8 - 29
    assert data[footer_at] == 0x02
    summary_start, _, crc = struct.unpack_from("<QQI", data, footer_at + 9)
    assert crc == zlib.crc32(data[summary_start : footer_at + 9 + 16])


def test_metadata_and_attachments(all_topics_log):
    path, _ = all_topics_log
    log = read_log(path)
    assert log.metadata["run"] == META["run"] and log.metadata["device"] == META["device"]
    assert log.metadata["log"]["schema_hash"] == schema_hash()
    assert log.metadata["log"]["format_version"] == "1"
    assert [a.name for a in log.attachments] == ["profile.yaml", "motor.yaml"]
    assert log.attachment("motor.yaml").text == "name: m\nsource: \u00b5H\n"
    assert log.attachment("motor.yaml").media_type == "application/yaml"
    with open(path, "rb") as f:
        reader = make_reader(f)
        assert {m.name: m.metadata for m in reader.iter_metadata()}["run"] == META["run"]
        assert {a.name: a.data for a in reader.iter_attachments()}[
            "profile.yaml"
        ] == b"name: paper-a\n"


def test_missing_fields_defaults_and_bad_input(tmp_path):
    path = tmp_path / "d.mcap"
    with LogWriter(path) as w:
        w.write("/pmsm/telemetry", 0.001, {"speed_rpm": 12.5, "t_s": 0.001})
        w.write("/pmsm/params", 0.01, {"estimator": "rls"})
        with pytest.raises(KeyError, match="speed_rmp"):
            w.write("/pmsm/telemetry", 0.002, {"speed_rmp": 1.0})
        with pytest.raises(ValueError, match="speed_rpm = 'x'"):
            w.write("/pmsm/telemetry", 0.002, {"speed_rpm": "x"})
        with pytest.raises(ValueError, match="s_a = 300"):
            w.write("/pmsm/capture", 0.002, {"s_a": 300})
        with pytest.raises(ValueError, match="t_s = -1"):
            w.write("/pmsm/telemetry", -1.0, {})
        with pytest.raises(KeyError, match="unknown topic"):
            w.write("/nope", 0.0, {})
    log = read_log(path)
    tel = log.topic("/pmsm/telemetry")
    assert tel["speed_rpm"][0] == 12.5 and math.isnan(tel["i_d_a"][0])
    par = log.topic("/pmsm/params")
    assert par["estimator"][0] == "rls" and not par["converged"][0]
    assert len(log.topic("/sim/truth")["t_s"]) == 0  # contract topic absent: empty columns
    with pytest.raises(KeyError):
        log.topic("/not/there")


# ----------------------------------------------------------------------------------- write_many


def test_write_many_is_write_in_bulk(tmp_path):
    rows = sample_rows("/pmsm/telemetry", 5000, dt=1e-3)
    ev = sample_rows("/pmsm/events", 3, t0=0.5)
    kw = dict(chunk_size=64 * 1024, chunk_span_s=0.7)  # chunks close on size and on time
    with LogWriter(tmp_path / "a.mcap", META, ATTACH, **kw) as w:
        write_rows(w, "/pmsm/telemetry", rows[:1000])
        write_rows(w, "/pmsm/events", ev)
        write_rows(w, "/pmsm/telemetry", rows[1000:])
    cols = {n: np.array([r[n] for r in rows]) for n in TOPICS["/pmsm/telemetry"].names}
    with LogWriter(tmp_path / "b.mcap", META, ATTACH, **kw) as w:
        assert w.write_many("/pmsm/telemetry", {k: v[:1000] for k, v in cols.items()}) == 1000
        w.write_many("/pmsm/events", ev)  # iterable of mappings
        struct_rows = np.zeros(4000, dtype=[(n, "f8") for n in cols])
        for n in cols:
            struct_rows[n] = cols[n][1000:]
        w.write_many("/pmsm/telemetry", struct_rows)  # structured array
    a, b = (tmp_path / "a.mcap").read_bytes(), (tmp_path / "b.mcap").read_bytes()
    assert a == b
    log = read_log(tmp_path / "b.mcap")
    assert_columns_equal(log.topic("/pmsm/telemetry"), rows, "/pmsm/telemetry")
    with open(tmp_path / "b.mcap", "rb") as f:
        assert make_reader(f).get_summary().statistics.chunk_count > 5


def test_deterministic_bytes(tmp_path):
    rows = sample_rows("/pmsm/capture", 2000, dt=50e-6)
    for name in ("a", "b"):
        with LogWriter(tmp_path / f"{name}.mcap", META, ATTACH) as w:
            write_rows(w, "/pmsm/capture", rows)
    assert (tmp_path / "a.mcap").read_bytes() == (tmp_path / "b.mcap").read_bytes()


@pytest.mark.parametrize("compression", available_compressions())
def test_compressions(tmp_path, compression):
    rows = sample_rows("/sim/truth", 500)
    with LogWriter(tmp_path / "c.mcap", compression=compression) as w:
        write_rows(w, "/sim/truth", rows)
    log = read_log(tmp_path / "c.mcap")
    assert log.metadata["log"]["compression"] == (compression or "none")
    assert_columns_equal(log.topic("/sim/truth"), rows, "/sim/truth")


# ----------------------------------------------------------------------------------- crash safety


def test_truncated_file_is_readable(tmp_path):
    rows = sample_rows("/pmsm/telemetry", 20000, dt=5e-4)
    st = sample_rows("/pmsm/status", 100, dt=0.1)
    path = tmp_path / "full.mcap"
    with LogWriter(path, META, ATTACH, chunk_size=256 * 1024) as w:
        for i in range(100):
            write_rows(w, "/pmsm/telemetry", rows[i * 200 : (i + 1) * 200])
            write_rows(w, "/pmsm/status", st[i : i + 1])
    data = path.read_bytes()
    for frac in (0.05, 0.33, 0.5, 0.77, 0.999):
        cut = tmp_path / "cut.mcap"
        cut.write_bytes(data[: int(len(data) * frac)])
        log = read_log(cut)
        assert not log.finalised
        assert log.metadata["run"] == META["run"] and len(log.attachments) == 2
        tel = log.topic("/pmsm/telemetry")
        k = len(tel["t_s"])
        assert k > 0 or frac < 0.1
        assert_columns_equal(tel, rows[:k], "/pmsm/telemetry")  # a prefix, exactly
        # mcap's own non-seeking reader recovers the same messages before the end of data
        n = 0
        with pytest.raises(Exception):  # noqa: B017  (the error type differs between mcap versions)
            for rec in StreamReader(io.BytesIO(cut.read_bytes())).records:
                if isinstance(rec, Message) and rec.channel_id == 1:
                    n += 1
        assert n == k
    # a file cut right after a chunk, before its message indexes: read record by record
    p = 8
    while True:
        op, ln = struct.unpack_from("<BQ", data, p)
        p += 9 + ln
        if op == 0x06:
            break
    cut.write_bytes(data[:p])
    log = read_log(cut)
    k = len(log.topic("/pmsm/telemetry")["t_s"])
    assert k > 0 and log.truncated is False
    assert_columns_equal(log.topic("/pmsm/telemetry"), rows[:k], "/pmsm/telemetry")


def test_rewrite_finalises_a_cut_log(all_topics_log, tmp_path):
    path, rows = all_topics_log
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[:-200])  # summary lost
    assert not read_log(cut).finalised
    rewrite_log(cut, tmp_path / "fixed.mcap")
    log = read_log(tmp_path / "fixed.mcap")
    assert log.finalised and log.metadata["run"] == META["run"] and len(log.attachments) == 2
    for topic, rs in rows.items():
        assert_columns_equal(log.topic(topic), rs, topic)
    with open(tmp_path / "fixed.mcap", "rb") as f:
        assert make_reader(f).get_summary().statistics.message_count == sum(map(len, rows.values()))


def _child(code: str, tmp_path: Path) -> subprocess.CompletedProcess:
    script = tmp_path / "child.py"
    script.write_text(textwrap.dedent(code))
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run(
        [sys.executable, str(script)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )


CHILD_HEAD = """
    import os, signal, sys
    from pmsm_hil.log.writer import LogWriter
    names = ["speed_ref_rpm", "speed_rpm", "i_d_a", "i_q_a"]
    def rows():
        i = 0
        while True:
            yield i * 5e-4, {n: float(i) for n in names}
            i += 1
"""


def test_killed_process_leaves_a_readable_log(tmp_path):
    res = _child(
        CHILD_HEAD
        + """
    w = LogWriter("k.mcap", {"run": {"seed": "1"}})
    for i, (t, r) in enumerate(rows()):
        w.write("/pmsm/telemetry", t, r)
        if i == 30000:       # 15 s of device time: 15 chunks flushed (1 s each)
            os.kill(os.getpid(), signal.SIGKILL)
    """,
        tmp_path,
    )
    assert res.returncode == -signal.SIGKILL, res.stderr
    log = read_log(tmp_path / "k.mcap")
    assert not log.finalised and log.metadata["run"] == {"seed": "1"}
    t = log.topic("/pmsm/telemetry")["t_s"]
    assert 28000 <= len(t) <= 30001
    np.testing.assert_array_equal(t, np.arange(len(t)) * 5e-4)


def test_ctrl_c_finalises_the_log(tmp_path):
    res = _child(
        CHILD_HEAD
        + """
    # Ctrl-C as in a terminal: a process started in the background by a non-interactive shell
    # inherits SIGINT ignored, and Python then installs no KeyboardInterrupt handler
    signal.signal(signal.SIGINT, signal.default_int_handler)
    w = LogWriter("c.mcap")
    try:
        for i, (t, r) in enumerate(rows()):
            w.write("/pmsm/telemetry", t, r)
            if i == 5000:
                os.kill(os.getpid(), signal.SIGINT)
    except KeyboardInterrupt:
        print("interrupted")
    finally:
        w.close()
        w.close()
    """,
        tmp_path,
    )
    assert res.returncode == 0 and "interrupted" in res.stdout, res.stderr
    log = read_log(tmp_path / "c.mcap")
    assert log.finalised and not log.problems
    assert 5000 <= log.counts["/pmsm/telemetry"] <= 5002


def test_close_from_a_signal_handler(tmp_path):
    res = _child(
        CHILD_HEAD
        + """
    w = LogWriter("s.mcap")
    def on_term(signum, frame):
        w.close()
        sys.exit(3)
    signal.signal(signal.SIGTERM, on_term)
    for i, (t, r) in enumerate(rows()):
        w.write("/pmsm/telemetry", t, r)
        if i == 7000:
            os.kill(os.getpid(), signal.SIGTERM)
    """,
        tmp_path,
    )
    assert res.returncode == 3, res.stderr
    log = read_log(tmp_path / "s.mcap")
    assert log.finalised and 7000 <= log.counts["/pmsm/telemetry"] <= 7002


def test_close_is_idempotent(tmp_path):
    w = LogWriter(tmp_path / "i.mcap")
    w.write("/pmsm/events", 0.0, {"kind": "started", "code": 8, "arg": 0, "text": "started"})
    w.close()
    size = (tmp_path / "i.mcap").stat().st_size
    w.close()
    with w:
        pass
    assert (tmp_path / "i.mcap").stat().st_size == size and w.closed
    with pytest.raises(ValueError, match="closed"):
        w.write("/pmsm/events", 1.0, {"kind": "host"})
    log = read_log(tmp_path / "i.mcap")
    assert log.finalised and log.topic("/pmsm/events")["text"][0] == "started"


def test_not_mcap(tmp_path):
    (tmp_path / "x.mcap").write_bytes(b"hello world")
    with pytest.raises(LogFormatError):
        read_log(tmp_path / "x.mcap")


# ----------------------------------------------------------------------------------- other files


def test_reads_files_of_other_writers(tmp_path):
    """mcap_ros2's writer puts schemas and channels inside chunks; a non-flat schema decodes through
    mcap_ros2."""
    from mcap_ros2.writer import Writer

    path = tmp_path / "other.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        td = TOPICS["/pmsm/status"]
        sch = w.register_msgdef(td.schema_name, td.msgdef)
        vec = w.register_msgdef("foo/msg/Vec", "float64[3] v\nstring name")
        rows = sample_rows("/pmsm/status", 50, dt=0.1)
        for r in rows:
            w.write_message("/pmsm/status", sch, r, log_time=round(r["t_s"] * 1e9))
            w.write_message("/foo", vec, {"v": [1.0, 2.0, r["t_s"]], "name": "x"}, log_time=0)
        w.finish()
    log = read_log(path)
    assert_columns_equal(log.topic("/pmsm/status"), rows, "/pmsm/status")
    foo = log.topic("/foo")
    assert list(foo["name"]) == ["x"] * 50 and foo["v"][3][2] == pytest.approx(0.3)


def test_damaged_chunk_is_skipped_and_reported(tmp_path):
    rows = sample_rows("/pmsm/telemetry", 6000, dt=5e-4)  # 3 s: at least 3 chunks
    path = tmp_path / "d.mcap"
    with LogWriter(path, META, ATTACH, compression="") as w:
        write_rows(w, "/pmsm/telemetry", rows)
    data = bytearray(path.read_bytes())
    p, chunks = 8, []
    while True:
        op, ln = struct.unpack_from("<BQ", data, p)
        if op == 0x06:
            chunks.append((p, ln))
        if op == 0x0F:
            break
        p += 9 + ln
    assert len(chunks) >= 3
    p, ln = chunks[1]  # the second chunk's records: one octet changed
    data[p + 9 + ln - 40] ^= 0xFF
    path.write_bytes(bytes(data))
    log = read_log(path)
    assert any("chunk" in pr and "skipped" in pr for pr in log.problems), log.problems
    t = log.topic("/pmsm/telemetry")["t_s"]
    assert 0 < len(t) < len(rows)
    missing = {r["t_s"] for r in rows} - set(t.tolist())
    assert missing and min(missing) > t[0] and max(missing) < t[-1]  # a middle piece


def test_flush_wall_s_puts_a_quiet_writers_data_on_disk(tmp_path):
    """With flush_wall_s the open chunk reaches the file once it has been open that long in wall
    time, whatever the device time: by the next message, or by flush_if_due() on a quiet link."""
    import time

    path = tmp_path / "wall.mcap"
    w = LogWriter(path, flush_wall_s=0.05)
    w.write("/pmsm/events", 0.0, {"kind": "host", "text": "a"})
    w.flush_if_due()
    assert "/pmsm/events" not in read_log(path).topics  # still in the open chunk
    time.sleep(0.06)
    w.flush_if_due()
    assert read_log(path).counts["/pmsm/events"] == 1  # on disk, the writer still open
    w.write("/pmsm/events", 0.001, {"kind": "host", "text": "b"})
    time.sleep(0.06)
    w.write("/pmsm/events", 0.002, {"kind": "host", "text": "c"})  # closes the chunk before it
    assert read_log(path).counts["/pmsm/events"] == 2
    assert w._msg_count == 2 and w.message_count == 3
    meta = read_log(path).metadata["log"]
    assert (meta["flush_wall_s"], meta["chunk_span_s"]) == ("0.05", "1.0")
    w.close()
    assert read_log(path).counts["/pmsm/events"] == 3
