"""A noisy serial line, for fault injection (tests, benchmarks/link_faults.py, `emulate
--corrupt-ppm/--drop-ppm`): in `flip_ppm` of a million octets one bit is flipped, `drop_ppm` of a
million octets are lost (an overrun, a framing error the UART discards). Seeded: the same octets
are hit on every run."""

from __future__ import annotations

import numpy as np


class LinkNoise:
    def __init__(self, flip_ppm: float = 0.0, drop_ppm: float = 0.0, seed: int = 1):
        if not (0 <= flip_ppm <= 1e6 and 0 <= drop_ppm <= 1e6):
            raise ValueError(f"noise rates must be 0..1e6 ppm, got {flip_ppm}, {drop_ppm}")
        self.p_flip = flip_ppm * 1e-6
        self.p_drop = drop_ppm * 1e-6
        self.rng = np.random.default_rng(seed)
        self.octets = 0
        self.flipped = 0
        self.dropped = 0

    def __bool__(self) -> bool:
        return bool(self.p_flip or self.p_drop)

    def __call__(self, data: bytes) -> bytes:
        n = len(data)
        self.octets += n
        if not n:
            return data
        k = self.rng.binomial(n, self.p_flip) if self.p_flip else 0
        d = self.rng.binomial(n, self.p_drop) if self.p_drop else 0
        if not (k or d):
            return data
        buf = bytearray(data)
        for i, bit in zip(self.rng.integers(0, n, k), self.rng.integers(0, 8, k), strict=False):
            buf[int(i)] ^= 1 << int(bit)
        self.flipped += k
        if d:
            gone = set(self.rng.integers(0, n, d).tolist())
            self.dropped += len(gone)
            buf = bytearray(b for j, b in enumerate(buf) if j not in gone)
        return bytes(buf)
