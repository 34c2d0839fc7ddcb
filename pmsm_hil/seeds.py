"""The emulator's noise seeds are whole numbers 0..SEED_MAX: a sweep file's seed and seed axis,
every command's --seed, `pmsm-hil bench --seeds`, the pytest plugin's --hil-seed (no heavy imports:
the CLI reads this at start)."""

from __future__ import annotations

import argparse

SEED_MAX = 2**31 - 1


def seed_arg(text: str) -> int:
    """An argparse ``type`` for --seed: a whole number 0..SEED_MAX (the seeds beyond it aliased
    those below: 2**32 + 1 ran as 1, -1 as 2**32 - 1)."""
    try:
        n = int(text)
    except ValueError:
        n = -1
    if not 0 <= n <= SEED_MAX:
        raise argparse.ArgumentTypeError(f"{text!r}: give a whole number 0..{SEED_MAX}")
    return n
