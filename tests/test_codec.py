"""Codec and framing (Python side): golden frames, round trips, streaming decoder, errors, resync."""

from __future__ import annotations

import json
import math
import random
import struct
from binascii import crc_hqx
from pathlib import Path

import pytest

from pmsm_hil.protocol import codec
from pmsm_hil.protocol.generated import BY_ID, BY_NAME, MAX_PAYLOAD, MESSAGES, WIRE_TYPES

GOLDEN = json.loads((Path(__file__).parent / "data" / "golden_frames.json").read_text())["vectors"]


def as_f32(x: float) -> float:
    return struct.unpack("<f", struct.pack("<f", x))[0]


def random_fields(rng: random.Random, spec, over_range: float = 1.0) -> dict:
    """Random field values; scaled ones span over_range times the representable range."""
    out = {}
    for f in spec.fields:
        _, _, lo, hi = WIRE_TYPES[f.type]

        def one(f=f, lo=lo, hi=hi):
            if f.scale is not None:
                return rng.uniform(lo * f.scale, hi * f.scale) * over_range
            if f.type == "f32":
                return rng.choice([0.0, -1.5, rng.uniform(-1e3, 1e3), rng.uniform(-1e-3, 1e-3)])
            return rng.randint(lo, hi)

        out[f.name] = one() if f.count == 1 else [one() for _ in range(f.count)]
    return out


def random_frames(rng: random.Random, n: int) -> list[tuple[bytes, tuple]]:
    """n encoded frames of random messages, with what they should decode to (msg_id, seq, payload)."""
    frames = []
    for i in range(n):
        spec = rng.choice(MESSAGES)
        payload = codec.encode_payload(spec.id, **random_fields(rng, spec))
        frames.append(
            (codec.encode_frame(spec.id, i & 0xFF, payload), (spec.id, i & 0xFF, payload))
        )
    return frames


# ------------------------------------------------------------------------------------ golden


def test_crc_is_ccitt_false():
    assert crc_hqx(b"123456789", 0xFFFF) == 0x29B1


def test_golden_covers_every_message():
    assert {v["name"] for v in GOLDEN} == set(BY_NAME)
    assert any(len(v["payload"]) // 2 == MAX_PAYLOAD for v in GOLDEN)
    assert any(
        "00" in [v["payload"][i : i + 2] for i in range(0, len(v["payload"]), 2)] for v in GOLDEN
    )


@pytest.mark.parametrize("vec", GOLDEN, ids=[v["label"] for v in GOLDEN])
def test_golden_vector(vec):
    frame = codec.encode(vec["name"], vec["seq"], **vec["fields"])
    assert frame.hex() == vec["frame"]
    assert codec.encode(vec["msg_id"], vec["seq"], **vec["fields"]) == frame
    payload = bytes.fromhex(vec["payload"])
    decoded = codec.decode_payload(vec["msg_id"], payload)
    assert {k: list(v) if isinstance(v, tuple) else v for k, v in decoded.items()} == vec["decoded"]
    dec = codec.FrameDecoder()
    (fr,) = dec.feed(frame)
    assert (fr.msg_id, fr.seq, fr.name, fr.fields) == (
        vec["msg_id"],
        vec["seq"],
        vec["name"],
        decoded,
    )


# -------------------------------------------------------------------------------- round trips


@pytest.mark.parametrize("spec", MESSAGES, ids=[m.name for m in MESSAGES])
def test_round_trip_random(spec):
    rng = random.Random(spec.id)
    for _ in range(200):
        fields = random_fields(rng, spec)
        payload = codec.encode_payload(spec.name, **fields)
        assert len(payload) == spec.length
        back = codec.decode_payload(spec.id, payload)
        for f in spec.fields:
            sent = fields[f.name] if f.count > 1 else [fields[f.name]]
            got = back[f.name] if f.count > 1 else [back[f.name]]
            assert len(got) == f.count
            for s, g in zip(sent, got, strict=False):
                if f.scale is not None:
                    assert abs(g - s) <= f.scale / 2 * (1 + 1e-9), (f.name, s, g)
                elif f.type == "f32":
                    assert g == as_f32(s)
                else:
                    assert g == s and isinstance(g, int)


@pytest.mark.parametrize(
    "spec", [m for m in MESSAGES if any(f.scale for f in m.fields)], ids=lambda m: m.name
)
def test_scaled_fields_saturate(spec):
    rng = random.Random(1000 + spec.id)
    for _ in range(50):
        fields = random_fields(rng, spec, over_range=3.0)
        back = codec.decode_payload(spec.id, codec.encode_payload(spec.name, **fields))
        for f in spec.fields:
            if f.scale is None:
                continue
            _, _, lo, hi = WIRE_TYPES[f.type]
            sent = fields[f.name] if f.count > 1 else [fields[f.name]]
            got = back[f.name] if f.count > 1 else [back[f.name]]
            for s, g in zip(sent, got, strict=False):
                expected = min(max(s, lo * f.scale), hi * f.scale)
                assert abs(g - expected) <= f.scale / 2 * (1 + 1e-9), (f.name, s, g)


def test_quantise_rules():
    assert codec.quantise(0.003, 0.002, "i16") == 2  # 1.5 LSB: half up
    assert codec.quantise(-0.003, 0.002, "i16") == -1  # -1.5 LSB: half up
    assert codec.quantise(-0.0031, 0.002, "i16") == -2
    assert codec.quantise(float("nan"), 0.1, "i16") == 0
    assert codec.quantise(float("inf"), 0.1, "i16") == 32767
    assert codec.quantise(float("-inf"), 0.1, "u16") == 0
    assert codec.quantise(2 * math.pi, 2 * math.pi / 65536, "u16") == 65535  # saturates, no wrap


def test_decode_payloads_matches_decode_payload():
    rng = random.Random(7)
    for spec in (BY_NAME["telem_fast"], BY_NAME["capture_chunk"], BY_NAME["params"]):
        payloads = [codec.encode_payload(spec.id, **random_fields(rng, spec)) for _ in range(20)]
        cols = codec.decode_payloads(spec.id, payloads)
        for i, p in enumerate(payloads):
            one = codec.decode_payload(spec.id, p)
            for name, value in one.items():
                assert cols[name][i].tolist() == pytest.approx(
                    list(value) if isinstance(value, tuple) else value, rel=1e-6, abs=1e-12
                )


def test_generated_tables_are_consistent():
    for spec in MESSAGES:
        assert spec.struct.size == spec.length
        assert BY_ID[spec.id] is spec and BY_NAME[spec.name] is spec
        assert sum(WIRE_TYPES[f.type][1] * f.count for f in spec.fields) == spec.length
    assert max(m.length for m in MESSAGES) == MAX_PAYLOAD


# ------------------------------------------------------------------------------- encode errors


def test_encode_errors_name_the_problem():
    good = dict(host_proto_version=1)
    with pytest.raises(codec.ProtocolError, match="unknown message 'helo'"):
        codec.encode("helo", 0, **good)
    with pytest.raises(codec.ProtocolError, match=r"missing fields .*host_proto_version"):
        codec.encode("hello", 0)
    with pytest.raises(codec.ProtocolError, match=r"unknown fields .*colour"):
        codec.encode("hello", 0, colour=3, **good)
    with pytest.raises(
        codec.ProtocolError, match=r"hello.host_proto_version=70000 is outside the u16"
    ):
        codec.encode("hello", 0, host_proto_version=70000)
    with pytest.raises(codec.ProtocolError, match="expected an integer"):
        codec.encode("hello", 0, host_proto_version=1.5)
    with pytest.raises(codec.ProtocolError, match="must be octets"):
        codec.encode("hello", 256, **good)
    fields = random_fields(random.Random(0), BY_NAME["capture_chunk"])
    fields["i_a_a"] = fields["i_a_a"][:7]
    with pytest.raises(codec.ProtocolError, match=r"capture_chunk.i_a_a: expected 8 values, got 7"):
        codec.encode("capture_chunk", 0, **fields)
    with pytest.raises(codec.ProtocolError, match="unknown message id 0xEE"):
        codec.decode_payload(0xEE, b"")
    with pytest.raises(codec.ProtocolError, match="hello: payload of 3 octets, expected 2"):
        codec.decode_payload(0x01, b"abc")


# ---------------------------------------------------------------------------- stream decoding


def test_stream_split_at_random_points():
    rng = random.Random(42)
    frames = random_frames(rng, 600)
    data = b"".join(f for f, _ in frames)
    dec = codec.FrameDecoder()
    got = []
    pos = 0
    while pos < len(data):
        step = rng.choice([1, 2, 3, 7, 50, 300, 4000])
        got += dec.feed_raw(data[pos : pos + step])
        pos += step
    assert got == [want for _, want in frames]
    assert dec.frames_ok == 600 and dec.bad_frames == 0 and dec.seq_gaps == 0
    assert dec.octets == len(data)


def test_feed_returns_decoded_frames():
    rng = random.Random(3)
    frames = random_frames(rng, 100)
    dec = codec.FrameDecoder()
    out = dec.feed(b"".join(f for f, _ in frames))
    assert [(fr.msg_id, fr.seq) for fr in out] == [(w[0], w[1]) for _, w in frames]
    for fr, (_, (msg_id, _, payload)) in zip(out, frames, strict=False):
        assert fr.name == BY_ID[msg_id].name
        assert fr.fields == codec.decode_payload(msg_id, payload)


def test_corrupted_frames_are_counted_and_dropped():
    rng = random.Random(5)
    frames = random_frames(rng, 400)
    stream, intact, corrupted, seen_gaps, lead = [], [], 0, 0, 0
    for frame, want in frames:
        if rng.random() < 0.3:
            b = bytearray(frame)
            i = rng.randrange(len(b) - 1)  # not the delimiter
            b[i] = rng.choice([x for x in range(1, 256) if x != b[i]])  # never a new 0x00
            stream.append(bytes(b))
            corrupted += 1
            lead += 0 if intact else 1  # lost before the first good frame: no gap to see
        else:
            stream.append(frame)
            intact.append(want)
            seen_gaps = corrupted - lead  # a gap shows only when a good frame follows it
    dec = codec.FrameDecoder()
    assert dec.feed_raw(b"".join(stream)) == intact
    assert dec.bad_frames == corrupted
    assert dec.frames_ok == len(intact)
    assert dec.seq_gaps == seen_gaps


def test_resync_after_garbage():
    rng = random.Random(9)
    frames = random_frames(rng, 5)
    wants = [w for _, w in frames]
    dec = codec.FrameDecoder()
    # garbage glued to the first frame loses that frame only
    out = dec.feed_raw(b"\x13\x37\x42" + b"".join(f for f, _ in frames))
    assert out == wants[1:]
    assert dec.bad_frames == 1
    # a stream opened mid-frame: the tail of a frame, then whole frames
    dec = codec.FrameDecoder()
    assert dec.feed_raw(frames[0][0][5:] + frames[1][0] + frames[2][0]) == wants[1:3]
    # idle zeros between frames are not errors
    dec = codec.FrameDecoder()
    assert dec.feed_raw(b"\x00\x00" + frames[0][0] + b"\x00" * 5 + frames[1][0]) == wants[:2]
    assert dec.bad_frames == 0


def test_overflow_is_skipped_to_the_next_delimiter():
    rng = random.Random(11)
    frames = random_frames(rng, 3)
    dec = codec.FrameDecoder()
    junk = bytes(rng.randrange(1, 256) for _ in range(3 * codec.MAX_ENCODED))
    out = []
    for i in range(0, len(junk), 100):  # the run arrives in pieces
        out += dec.feed_raw(junk[i : i + 100])
    out += dec.feed_raw(b"\x00" + b"".join(f for f, _ in frames))
    assert out == [w for _, w in frames]
    assert dec.len_errors == 1 and dec.bad_frames == 1


def test_appended_zero_is_caught_by_the_length_check():
    # a delimiter corrupted into 0x01 and followed by an idle 0x00 decodes as the frame plus one
    # 0x00 octet, which CRC-16/CCITT-FALSE cannot see
    frame = codec.encode("hello", 1, host_proto_version=1)
    dec = codec.FrameDecoder()
    assert dec.feed_raw(frame[:-1] + b"\x01\x00") == []
    assert dec.len_errors == 1


def test_unknown_id_and_short_frames():
    dec = codec.FrameDecoder()
    unknown = codec.encode_frame(0xEE, 0, b"\x01\x02")
    assert dec.feed_raw(unknown) == [(0xEE, 0, b"\x01\x02")]
    assert dec.feed(unknown) == []
    assert dec.unknown_id == 1
    dec.feed_raw(b"\x01\x00\x03\x11\x22\x00\x05\x11\x00")
    assert (dec.short_errors, dec.cobs_errors) == (2, 1)


def test_sequence_gaps():
    rng = random.Random(13)
    frames = random_frames(rng, 300)
    kept = [f for i, (f, _) in enumerate(frames) if i % 7 != 3]  # the last frame is kept
    dec = codec.FrameDecoder()
    dec.feed_raw(b"".join(kept))
    assert dec.seq_gaps == len(frames) - len(kept)


# Frames worked out by hand from docs/protocol.md (not by the codec under test):
#   heartbeat (id 0x09), seq 5, counter = 0x01020304 (u32, little-endian):
#     id seq payload = 09 05 04 03 02 01; CRC-16/CCITT-FALSE over them = 0x8047 (high first)
#     no 0x00 among the 8 octets: COBS = code 0x09 + the 8 octets; then the delimiter
#   hello (id 0x01), seq 0, host_proto_version = 2 (u16): 01 00 02 00, CRC 0x9416
#     COBS blocks at each 0x00: [01] [02] [94 16] -> 02 01 | 02 02 | 03 94 16; delimiter
HAND_FRAMES = [
    (("heartbeat", 5, {"counter": 0x01020304}), bytes.fromhex("09 09 05 04 03 02 01 80 47 00")),
    (("hello", 0, {"host_proto_version": 2}), bytes.fromhex("02 01 02 02 03 94 16 00")),
]


@pytest.mark.parametrize("msg, octets", HAND_FRAMES)
def test_frames_worked_out_by_hand_from_the_written_rules(msg, octets):
    name, seq, fields = msg
    assert codec.encode(name, seq, **fields) == octets
    dec = codec.FrameDecoder()
    (fr,) = dec.feed(octets)
    assert (fr.name, fr.seq, fr.fields) == (name, seq, fields)
