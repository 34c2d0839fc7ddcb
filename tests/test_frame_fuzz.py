"""Randomised test of the firmware's frame parser (C, through ctypes on the built extension).

Random octets and corrupted valid frames (bit flips, truncations, insertions, deletions) with a fixed
seed: the parser must not crash, every FRAME_OK must be a frame that was sent (in order), every intact
frame after a delimiter must arrive, and the Python FrameDecoder must accept exactly the same frames.
"""

from __future__ import annotations

import ctypes
import random

import pmsm_hil._fw as fw
import pytest

from pmsm_hil.protocol import codec
from pmsm_hil.protocol.generated import MESSAGES

FRAME_OK = 1
FRAME_ERRORS = {-1, -2, -3, -4}


def load_lib() -> ctypes.CDLL:
    lib = ctypes.CDLL(fw.__file__)
    for name in (
        "frame_parser_size",
        "frame_parser_init",
        "frame_parser_push",
        "frame_parser_frame",
    ):
        if not hasattr(lib, name):
            pytest.fail(
                f"{fw.__file__} lacks {name}: rebuild the extension with `pip install -e .`"
            )
    lib.frame_parser_size.restype = ctypes.c_uint16
    lib.frame_parser_init.argtypes = [ctypes.c_void_p]
    lib.frame_parser_init.restype = None
    lib.frame_parser_push.argtypes = [ctypes.c_void_p, ctypes.c_uint16]
    lib.frame_parser_push.restype = ctypes.c_int16
    lib.frame_parser_frame.argtypes = [
        ctypes.c_void_p,
        ctypes.POINTER(ctypes.c_uint16),
        ctypes.c_uint16,
    ]
    lib.frame_parser_frame.restype = ctypes.c_uint16
    return lib


LIB = load_lib()


class CParser:
    def __init__(self) -> None:
        self.mem = ctypes.create_string_buffer(LIB.frame_parser_size())
        LIB.frame_parser_init(self.mem)
        self.out = (ctypes.c_uint16 * (codec.MAX_RAW + 2))()
        self.errors = 0

    def feed(self, data: bytes) -> list[tuple[int, int, bytes]]:
        push, mem, frames = LIB.frame_parser_push, self.mem, []
        for octet in data:
            r = push(mem, octet)
            if r == FRAME_OK:
                n = LIB.frame_parser_frame(mem, self.out, len(self.out))
                assert n >= 2
                frames.append((self.out[0], self.out[1], bytes(self.out[2:n])))
            elif r:
                assert r in FRAME_ERRORS, f"unexpected parser result {r}"
                self.errors += 1
        return frames


def is_subsequence(got: list, sent: list) -> bool:
    it = iter(sent)
    return all(any(g == s for s in it) for g in got)


def valid_frames(rng: random.Random, n: int) -> list[tuple[bytes, tuple[int, int, bytes]]]:
    """Frames of random messages with random payload octets (every field value is legal on the wire)."""
    out = []
    for i in range(n):
        spec = rng.choice(MESSAGES)
        payload = bytes(rng.randrange(256) for _ in range(spec.length))
        out.append((codec.encode_frame(spec.id, i & 0xFF, payload), (spec.id, i & 0xFF, payload)))
    return out


def corrupt(rng: random.Random, frame: bytes) -> bytes:
    """The frame damaged in one random way; never the frame itself (two flips of one bit cancel)."""
    while (bad := _damage(rng, frame)) == frame:
        pass
    return bad


def _damage(rng: random.Random, frame: bytes) -> bytes:
    b = bytearray(frame)
    kind = rng.randrange(5)
    if kind == 0:  # 1..3 bit flips anywhere, delimiter included
        for _ in range(rng.randint(1, 3)):
            i = rng.randrange(len(b))
            b[i] ^= 1 << rng.randrange(8)
    elif kind == 1:  # truncated, delimiter kept
        b = b[: rng.randrange(1, len(b) - 1)] + b"\x00"
    elif kind == 2:  # truncated, delimiter lost too
        b = b[: rng.randrange(1, len(b) - 1)]
    elif kind == 3:  # 1..4 random octets inserted inside the frame
        for _ in range(rng.randint(1, 4)):  # (a 0x00 before or after it would leave it whole)
            b.insert(rng.randrange(1, len(b) - 1), rng.randrange(256))
    else:  # 1..3 octets deleted
        for _ in range(rng.randint(1, 3)):
            if len(b) > 1:
                del b[rng.randrange(len(b))]
    return bytes(b)


def test_random_octets():
    rng = random.Random(20240601)
    parser, dec = CParser(), codec.FrameDecoder()
    for zero_prob in (0.0, 0.01, 0.05, 0.3):
        data = bytes(
            0 if rng.random() < zero_prob else rng.randrange(1, 256) for _ in range(40_000)
        )
        assert parser.feed(data) == []
        assert dec.feed_raw(data) == []
    assert parser.errors > 0


def test_corrupted_frames():
    rng = random.Random(1234)
    frames = valid_frames(rng, 6000)
    parts, must_arrive = [], []
    for frame, want in frames:
        if rng.random() < 0.5:
            parts.append(corrupt(rng, frame))
        else:
            if not parts or parts[-1].endswith(b"\x00"):  # nothing damaged runs into it
                must_arrive.append(want)
            parts.append(frame)
    data = b"".join(parts)
    got_c = CParser().feed(data)
    dec = codec.FrameDecoder()
    got_py = dec.feed_raw(data)
    # Every accepted frame is one that was sent, in order. (Not only the intact ones: two damaged
    # neighbours can rebuild a frame exactly, e.g. one that lost its delimiter followed by one that
    # lost its first octet, and those octets on the line are then a good frame.)
    assert is_subsequence(got_c, [want for _, want in frames]), (
        "the C parser accepted a frame never sent"
    )
    assert is_subsequence(must_arrive, got_c), "the C parser lost an intact frame after a delimiter"
    assert got_py == got_c, "the C parser and the Python decoder disagree"
    assert len(must_arrive) > 2000


def test_valid_frames_with_random_chunking_and_junk():
    rng = random.Random(77)
    frames = valid_frames(rng, 500)
    parts, sent = [], []
    for frame, want in frames:
        if rng.random() < 0.1:  # junk ending in a delimiter between frames
            parts.append(
                bytes(rng.randrange(1, 256) for _ in range(rng.randrange(1, 300))) + b"\x00"
            )
        parts.append(frame)
        sent.append(want)
    parser = CParser()
    assert parser.feed(b"".join(parts)) == sent
