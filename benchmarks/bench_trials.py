"""The benchmarks' runs as trials (pmsm_hil.bench.trials): `pmsm-hil bench sensorless` (its
default scenarios, rigs and seeds) and `pmsm-hil bench identify --rigs default,lab-typical --seeds
1-10` with 1 and 2 local Dask workers, interleaved, each into a fresh folder: wall time, runs per
minute, the ratio, and whether the tables are the same byte for byte.

    nice python3 benchmarks/bench_trials.py [--repeat 2] [--only sensorless|identify]

The wall times include the cluster's start (a couple of seconds). On a machine shared with other
work the ratio moves with the load; the load average is printed with the figures.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CLI = [sys.executable, "-m", "pmsm_hil.cli.main", "bench"]
BENCHES = {
    # name: (arguments, table file, number of runs)
    "sensorless": (["sensorless"], "sensorless.md", 12),
    "identify": (
        ["identify", "--rigs", "default,lab-typical", "--seeds", "1-10"],
        "identify-rigs.md",
        20,
    ),
}


def one(args: list[str], workers: int, out: Path) -> float:
    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    r = subprocess.run(
        [*CLI, *args, "--out", str(out), "--workers", str(workers)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tempfile.gettempdir(),
    )
    if r.returncode != 0:
        sys.exit(f"bench {' '.join(args)} --workers {workers}: exit {r.returncode}\n{r.stderr}")
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--only", choices=sorted(BENCHES), default=None)
    a = ap.parse_args()
    print(f"load average at the start: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as tmp:
        for name, (args, table, n) in BENCHES.items():
            if a.only and name != a.only:
                continue
            times: dict[int, list[float]] = {1: [], 2: []}
            same = True
            for _ in range(a.repeat):
                for w in (1, 2):
                    times[w].append(one(args, w, Path(tmp, f"{name}-{w}")))
                same &= Path(tmp, f"{name}-1", table).read_bytes() == (
                    Path(tmp, f"{name}-2", table).read_bytes()
                )
            t1, t2 = statistics.median(times[1]), statistics.median(times[2])
            print(
                f"bench {name} ({n} runs), median of {a.repeat}: 1 worker {t1:.1f} s "
                f"({60 * n / t1:.0f} runs/min), 2 workers {t2:.1f} s ({60 * n / t2:.0f} runs/min): "
                f"{t1 / t2:.2f}x; tables {'identical' if same else 'DIFFERENT'}"
            )


if __name__ == "__main__":
    main()
