"""Property tests of the host's decoding path against random and mutated input (hypothesis):
framing round trips whatever the read boundaries, nothing unsent is accepted from a mutated
stream, payloads round trip through their fields, CAN messages reassemble, and the recorder
logs whatever valid frames it gets. Derandomised: the same examples on every run."""

from __future__ import annotations

import math
import struct

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pmsm_hil.log.reader import read_log
from pmsm_hil.log.writer import LogWriter
from pmsm_hil.protocol import codec
from pmsm_hil.protocol.can_link import CanDecoder, encode_payload_frames
from pmsm_hil.protocol.generated import BY_ID, MESSAGES
from pmsm_hil.recorder import Recorder

SETTINGS = settings(
    derandomize=True,
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
D2H = [m for m in MESSAGES if m.dir == "d2h"]


def _no_nan(spec, payload: bytes) -> bool:
    """True when no f32 field carries a NaN (its bit pattern need not survive a float round trip)."""
    values = spec.struct.unpack(payload)
    return not any(isinstance(v, float) and math.isnan(v) for v in values)


@st.composite
def raw_messages(draw, specs=MESSAGES):
    spec = draw(st.sampled_from(specs))
    payload = draw(st.binary(min_size=spec.length, max_size=spec.length))
    return spec.id, draw(st.integers(0, 255)), payload


@SETTINGS
@given(st.lists(raw_messages(), min_size=1, max_size=12), st.lists(st.integers(1, 64), min_size=1))
def test_frames_round_trip_whatever_the_read_boundaries(msgs, cuts):
    stream = b"".join(codec.encode_frame(i, s, p) for i, s, p in msgs)
    dec = codec.FrameDecoder()
    out, pos, k = [], 0, 0
    while pos < len(stream):
        n = cuts[k % len(cuts)]
        out += dec.feed_raw(stream[pos : pos + n])
        pos, k = pos + n, k + 1
    assert out == msgs
    assert dec.bad_frames == 0


@SETTINGS
@given(st.lists(raw_messages(), min_size=2, max_size=8), st.data())
def test_a_mutated_stream_never_yields_a_frame_that_was_not_sent(msgs, data):
    stream = bytearray(b"".join(codec.encode_frame(i, s, p) for i, s, p in msgs))
    for _ in range(data.draw(st.integers(1, 6))):
        kind = data.draw(st.sampled_from(["flip", "drop", "insert"]))
        at = data.draw(st.integers(0, len(stream) - 1))
        if kind == "flip":
            stream[at] ^= 1 << data.draw(st.integers(0, 7))
        elif kind == "drop":
            del stream[at : at + data.draw(st.integers(1, 8))]
        else:
            stream[at:at] = data.draw(st.binary(min_size=1, max_size=8))
        if not stream:
            break
    got = codec.FrameDecoder().feed_raw(bytes(stream) + b"\x00")
    assert all(m in msgs for m in got)


@SETTINGS
@given(raw_messages())
def test_payloads_round_trip_through_their_fields(msg):
    msg_id, _, payload = msg
    spec = BY_ID[msg_id]
    if not _no_nan(spec, payload):
        return
    fields = codec.decode_payload(msg_id, payload)
    again = codec.decode_payload(msg_id, codec.encode_payload(msg_id, **fields))
    assert again == fields


@SETTINGS
@given(st.lists(raw_messages(D2H), min_size=1, max_size=8))
def test_can_messages_reassemble(msgs):
    msgs = [(i, s, p) for i, s, p in msgs if _no_nan(BY_ID[i], p)]
    dec = CanDecoder()
    frames = [fr for i, s, p in msgs for fr in encode_payload_frames(i, s, p)]
    got = [(f.msg_id, f.seq, f.fields) for f in dec.feed(frames)]
    assert got == [(i, s, codec.decode_payload(i, p)) for i, s, p in msgs]
    assert dec.bad_frames == 0


@SETTINGS
@given(st.lists(raw_messages(D2H), min_size=1, max_size=40))
def test_the_recorder_logs_any_valid_device_frames(tmp_path_factory, msgs):
    msgs = [(i, s, p) for i, s, p in msgs if _no_nan(BY_ID[i], p)]
    path = tmp_path_factory.mktemp("rec") / "r.mcap"
    frames = codec.FrameDecoder().feed(b"".join(codec.encode_frame(i, s, p) for i, s, p in msgs))
    with LogWriter(path) as w:
        rec = Recorder(w, 50e-6, ["a", "b"])
        rec.frames(frames)
    log = read_log(path)
    assert log.finalised
    logged = {
        "telem_fast": "/pmsm/telemetry",
        "params": "/pmsm/params",
        "status": "/pmsm/status",
        "sim_truth": "/sim/truth",
        "event": "/pmsm/events",
    }
    for name, topic in logged.items():
        n = sum(1 for f in frames if f.name == name)
        assert log.counts.get(topic, 0) == n, name


def test_the_nan_filter_sees_a_nan_float():
    spec = next(m for m in MESSAGES if m.fields[0].type == "f32")
    nan = struct.pack("<f", float("nan")) + bytes(spec.length - 4)
    assert not _no_nan(spec, nan) and _no_nan(spec, bytes(spec.length))
