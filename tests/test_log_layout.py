"""The log file's layout and the writer's support (pmsm_hil.log.mcap_file, .columns,
.write_support): the file is the `mcap` library writer's octet for octet, the reader's gather
gives each message's octets, and holding signals never leaves them blocked. The writer's and the
reader's behaviour: tests/test_log.py."""

from __future__ import annotations

import io
import signal

import numpy as np
import pytest
from mcap.reader import make_reader
from test_log import ATTACH, META, sample_rows

from pmsm_hil.log.reader import read_log
from pmsm_hil.log.schemas import TOPICS, codec_for
from pmsm_hil.log.write_support import available_compressions
from pmsm_hil.log.writer import LogWriter


@pytest.mark.parametrize("compression", available_compressions())
def test_same_file_as_the_mcap_library_writer(tmp_path, compression):
    """The project lays the records out itself (pmsm_hil.log.mcap_file); the file is the one the
    `mcap` library's Writer writes for the same records, octet for octet, and the library's
    readers give every message back."""
    from mcap.writer import CompressionType, Writer

    from pmsm_hil.log.schemas import MESSAGE_ENCODING, SCHEMA_ENCODING
    from pmsm_hil.log.writer import LIBRARY, PROFILE

    topics = ["/pmsm/telemetry", "/pmsm/events", "/sim/truth", "/pmsm/params"]
    rows = {t: sample_rows(t, 700 if t == "/pmsm/telemetry" else 60) for t in topics}
    order = sorted(((r["t_s"], k, t) for t in topics for k, r in enumerate(rows[t])))
    flush_at = {100, 101, 900}  # chunks closed here (and by the size bound)
    path = tmp_path / "ours.mcap"
    with LogWriter(path, META, ATTACH, compression=compression, chunk_size=20000) as w:
        for i, (_t, k, t) in enumerate(order):
            w.write(t, rows[t][k]["t_s"], {n: v for n, v in rows[t][k].items() if n != "t_s"})
            if i in flush_at:
                w.flush()
    kind = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "": CompressionType.NONE}
    ref = io.BytesIO()
    lib = Writer(ref, chunk_size=1 << 62, compression=kind[compression], enable_data_crcs=True)
    lib.start(PROFILE, LIBRARY)
    for name, rec in read_log(path).metadata.items():
        lib.add_metadata(name, rec)
    for name, media, data in ATTACH:
        lib.add_attachment(0, 0, name, media, data)
    schemas: dict[str, int] = {}
    channels: dict[str, int] = {}
    seq: dict[str, int] = {}
    size = 0
    for i, (_t, k, t) in enumerate(order):
        td = TOPICS[t]
        if t not in channels:
            text = td.msgdef.encode()
            if td.schema_name not in schemas:
                schemas[td.schema_name] = lib.register_schema(td.schema_name, SCHEMA_ENCODING, text)
                size += 21 + len(td.schema_name) + len(SCHEMA_ENCODING) + len(text)
            channels[t] = lib.register_channel(t, MESSAGE_ENCODING, schemas[td.schema_name], {})
            size += 25 + len(t) + len(MESSAGE_ENCODING)
        row = rows[t][k]
        data = codec_for(td).encode([row[n] for n in td.names])
        lt = round(row["t_s"] * 1e9)
        lib.add_message(channels[t], lt, data, lt, seq.get(t, 0))
        seq[t] = seq.get(t, 0) + 1
        size += 31 + len(data)
        if i in flush_at or size >= 20000:
            lib.flush()
            size = 0
    lib.finish()
    assert path.read_bytes() == ref.getvalue()
    with open(path, "rb") as f:
        got = list(make_reader(f).iter_messages())
    assert len(got) == len(order)


def test_gather_is_the_messages_one_after_the_other():
    """columns.gather, whichever way it takes (rows of one width, rows cut to their sizes, an
    index per octet), gives each message's octets in order."""
    from pmsm_hil.log.columns import gather

    rnd = np.random.default_rng(3)
    for _ in range(300):
        buf = rnd.integers(0, 255, int(rnd.integers(50, 3000)), dtype=np.uint8)
        sizes = rnd.integers(1, 40, int(rnd.integers(1, 30))).astype(np.int64)
        if rnd.random() < 0.3:
            sizes[:] = sizes[0]
        starts = np.array([rnd.integers(0, len(buf) - s + 1) for s in sizes], np.int64)
        want = np.concatenate([buf[a : a + s] for a, s in zip(starts, sizes, strict=True)])
        np.testing.assert_array_equal(gather(buf, starts, sizes), want)


def test_signals_held_never_leaves_the_mask_blocked(monkeypatch):
    """A signal already pending when the writer blocks SIGINT is handled as the block returns,
    before the old mask is recorded; the mask must still be restored (a test child inherited a
    blocked SIGINT once and looped forever)."""

    from pmsm_hil.log import write_support

    if not hasattr(signal, "pthread_sigmask"):
        pytest.skip("no pthread_sigmask")
    real = signal.pthread_sigmask
    before = real(signal.SIG_BLOCK, set())

    def interrupted(how, mask):
        out = real(how, mask)
        if how == signal.SIG_BLOCK:
            raise KeyboardInterrupt  # as the pending SIGINT's handler would, right after the call
        return out

    monkeypatch.setattr(signal, "pthread_sigmask", interrupted)
    with pytest.raises(KeyboardInterrupt), write_support.signals_held():
        pass
    monkeypatch.setattr(signal, "pthread_sigmask", real)
    assert real(signal.SIG_BLOCK, set()) == before
