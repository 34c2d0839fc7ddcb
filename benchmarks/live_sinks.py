"""Host cost of `run --foxglove`: what the Foxglove sink adds per telemetry frame, and what a
subscribed client costs per published message, against the recorder's own cost per frame.

    python3 benchmarks/live_sinks.py [--repeat 5] [--frames 20000]

Prints, in µs per message, best and median of the repeats:
- recorder: decode-free Recorder._on_telem_fast into an in-memory MCAP writer (the baseline),
- recorder + sink: the same with a FoxgloveSink (no client: every message is decimated away or
  skipped because nobody listens),
- publish, client listening: JSON encoding and foxglove-sdk's log call for one admitted message.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from pmsm_hil.live.foxglove import FoxgloveSink
from pmsm_hil.log.writer import LogWriter
from pmsm_hil.recorder import TELEMETRY_FIELDS, Recorder


def frames(n: int) -> list[dict]:
    return [{"tick": 10 * i, **{k: 0.5 + i * 1e-3 for k in TELEMETRY_FIELDS}} for i in range(n)]


def time_recorder(rows: list[dict], sinks, out: Path) -> float:
    with LogWriter(out, {}) as w:
        rec = Recorder(w, 50e-6, ["a"], sinks)
        t = time.perf_counter()
        for f in rows:
            rec._on_telem_fast(f)
        return (time.perf_counter() - t) / len(rows) * 1e6


def time_publish(sink: FoxgloveSink, n: int) -> float:
    ch = sink._channels["/pmsm/telemetry"]
    row = {k: 0.5 for k in TELEMETRY_FIELDS}
    sink.rates["/pmsm/telemetry"] = float("inf")  # admit everything: measure the send path
    sink._gates.clear()
    orig = type(ch).has_sinks
    type(ch).has_sinks = lambda self: True
    try:
        t = time.perf_counter()
        for i in range(n):
            sink.publish("/pmsm/telemetry", i * 5e-4, row)
        return (time.perf_counter() - t) / n * 1e6
    finally:
        type(ch).has_sinks = orig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--frames", type=int, default=20000)
    args = ap.parse_args()
    rows = frames(args.frames)
    base, with_sink, publish = [], [], []
    with tempfile.TemporaryDirectory() as d:
        for r in range(args.repeat):  # interleaved
            base.append(time_recorder(rows, [], Path(d) / f"a{r}.mcap"))
            sink = FoxgloveSink(0)
            try:
                with_sink.append(time_recorder(rows, [sink], Path(d) / f"b{r}.mcap"))
                publish.append(time_publish(sink, args.frames // 4))
            finally:
                sink.close()
    for name, xs in (
        ("recorder", base),
        ("recorder + sink, no client", with_sink),
        ("publish, client listening", publish),
    ):
        print(f"{name:28s} best {min(xs):6.2f} µs/msg   median {statistics.median(xs):6.2f} µs/msg")
    print(
        f"sink overhead: {statistics.median(with_sink) / statistics.median(base):.2f}x the recorder "
        f"alone (median); at 2 kHz telemetry: {2000 * (statistics.median(with_sink) - statistics.median(base)) / 1e4:.3f} % of one core"
    )


if __name__ == "__main__":
    main()
