"""N runs of one profile at the same time, each with its own emulator process, on serial and on
CAN: how many succeed (exit 0, complete log), and how long the batch takes. Two cores shared by
eight runs and their eight emulators is the load the heartbeat must survive.

    python3 benchmarks/parallel_runs.py [--n 8] [--profile tests/data/short.yaml] [--links serial,can]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def batch(n: int, profile: str, link: str, out: Path) -> tuple[int, list[str], float]:
    extra = ["--can"] if link == "can" else []
    t0 = time.monotonic()
    procs = [
        subprocess.Popen(
            [
                sys.executable,
                "-m",
                "pmsm_hil.cli.main",
                "run",
                profile,
                "--no-live",
                "--seed",
                str(k + 1),
                "--out",
                str(out / f"{link}-{k}.mcap"),
                *extra,
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for k in range(n)
    ]
    failures = []
    for k, p in enumerate(procs):
        stdout, stderr = p.communicate(timeout=900)
        if p.returncode != 0 or "all plateaus within bounds" not in stdout:
            last = (stderr.strip().splitlines() or stdout.strip().splitlines() or ["?"])[-1]
            failures.append(f"run {k}: exit {p.returncode}: {last}")
    return n - len(failures), failures, time.monotonic() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--profile", default=str(ROOT / "tests" / "data" / "short.yaml"))
    ap.add_argument("--links", default="serial,can")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        for link in args.links.split(","):
            ok, failures, wall = batch(args.n, args.profile, link, Path(d))
            print(f"{link}: {ok}/{args.n} parallel runs succeeded in {wall:.1f} s wall")
            for f in failures:
                print(f"  {f}")


if __name__ == "__main__":
    main()
