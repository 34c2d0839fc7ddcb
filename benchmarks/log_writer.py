"""Log writer throughput: telemetry messages per second through LogWriter.write(), best and median
of several runs, against the fastest link's message rate (docs/log-format.md).

    python3 benchmarks/log_writer.py [--repeat 5] [--n 40000]
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from pmsm_hil.log.schemas import TOPICS
from pmsm_hil.log.writer import LogWriter

LINK_MESSAGES_S = 2000 + 4 * 100 + 10 + 100   # fast frames + params x4 + status + truth at the defaults


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--n", type=int, default=40000)
    args = ap.parse_args()
    names = TOPICS["/pmsm/telemetry"].names[1:]
    rows = [{k: i * 1e-3 + j for j, k in enumerate(names)} for i in range(args.n)]
    rates = []
    with tempfile.TemporaryDirectory() as d:
        for rep in range(args.repeat):
            t0 = time.perf_counter()
            with LogWriter(Path(d) / f"t{rep}.mcap") as w:
                for i, r in enumerate(rows):
                    w.write("/pmsm/telemetry", i * 5e-4, r)
            rates.append(args.n / (time.perf_counter() - t0))
    best, med = max(rates), statistics.median(rates)
    print(f"LogWriter.write: best {best:,.0f} messages/s, median {med:,.0f} messages/s "
          f"({args.repeat} runs of {args.n})")
    print(f"headroom over the default serial telemetry ({LINK_MESSAGES_S} messages/s): "
          f"best {best / LINK_MESSAGES_S:.0f}x, median {med / LINK_MESSAGES_S:.0f}x")


if __name__ == "__main__":
    main()
