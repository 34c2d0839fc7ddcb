"""Long logs: `pmsm-hil report` of a one-hour log and `pmsm-hil log recover` of that log cut short.

    nice python3 benchmarks/long_logs.py [--repeat 3] [--log hour.mcap] [--cut 0.7] [--base DIR]

The one-hour log at the contract's fastest rates is benchmarks/end_to_end.py's (written once by
benchmarks/log_reader.py's generator and kept at --log). Each command runs in a fresh process:
wall time, CPU time and peak RSS, medians over --repeat (the worst beside them). `log recover`
gets the first --cut of the file (a killed writer's log: no summary, the last chunk cut). With
`--base DIR` another source tree's commands run interleaved with this one's and the speed-up is
printed per pair (benchmarks/end_to_end.py explains the tree).
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from end_to_end import _pairs, hour_log, interleaved, med


def bench(name: str, command, repeat: int, base: str | None) -> None:
    """``command(out)`` -> the argument list after the CLI for a run writing ``out`` (removed
    after the run: a recovered hour is most of a GiB)."""
    with tempfile.TemporaryDirectory() as d:

        def remove(i: int) -> None:
            out = os.path.join(d, f"out-{i}")
            if os.path.isdir(out):
                shutil.rmtree(out)
            elif os.path.exists(out):
                os.remove(out)

        runs = interleaved(
            name, repeat, base, lambda i: command(os.path.join(d, f"out-{i}")), after=remove
        )
    for label, rs in runs.items():
        w, c, m = ([r[k] for r in rs] for k in ("wall_s", "cpu_s", "rss_mib"))
        print(
            f"{name}, {label}, {repeat} runs: median {med(w):.1f} s wall (worst {max(w):.1f} s), "
            f"CPU {med(c):.1f} s, peak RSS {med(m):.0f} MiB (worst {max(m):.0f} MiB)"
        )
    _pairs(name, runs, "wall_s")
    if "base" in runs:
        ratios = [b["rss_mib"] / a["rss_mib"] for a, b in zip(*runs.values(), strict=True)]
        print(f"  {name}: base / this tree, peak RSS: median {med(ratios):.2f}x")


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--log", default=None, help="the one-hour log (written there if missing)")
    ap.add_argument("--cut", type=float, default=0.7, help="the part of it `log recover` gets")
    ap.add_argument("--base", default=None, help="another source tree to compare with")
    ap.add_argument("--skip", default="", help="comma-separated: report, recover")
    args = ap.parse_args()
    skip = set(filter(None, args.skip.split(",")))
    print(f"load average at the start: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    hour = hour_log(args.log)
    size = os.path.getsize(hour)
    if "report" not in skip:
        bench(
            f"report of one hour at 2 kHz ({size / 2**20:.0f} MiB)",
            lambda out: ["report", hour, "-o", out],
            args.repeat,
            args.base,
        )
    if "recover" not in skip:
        with tempfile.TemporaryDirectory() as d:
            cut = os.path.join(d, "cut.mcap")
            with open(hour, "rb") as src, open(cut, "wb") as dst:
                left = int(size * args.cut)
                while left > 0:
                    block = src.read(min(left, 64 << 20))
                    dst.write(block)
                    left -= len(block)
            bench(
                f"log recover of its first {args.cut:.0%} ({size * args.cut / 2**20:.0f} MiB, "
                f"cut short)",
                lambda out: ["log", "recover", cut, "-o", out],
                args.repeat,
                args.base,
            )


if __name__ == "__main__":
    main()
