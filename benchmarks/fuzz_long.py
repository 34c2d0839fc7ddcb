"""The long fuzz run (docs/faults.md): builds the libFuzzer targets (make -C firmware fuzz, which
needs clang) and runs each for a number of executions from its seed corpus, with ASan and UBSan;
prints the executions, crashes and sanitizer reports per target and in total. A finding leaves
its input as firmware/build/fuzz/NAME-crash-* and makes the exit code 1.

    python3 benchmarks/fuzz_long.py --runs fuzz_frame=5000000 fuzz_can=5000000 fuzz_fw=100000 \
        [--max-seconds 900]    # each target stops at its executions or at this time, whichever first
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FW = ROOT / "firmware"
BUILD = FW / "build" / "fuzz"
DEFAULT = {"fuzz_frame": 5_000_000, "fuzz_can": 5_000_000, "fuzz_fw": 100_000}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", nargs="*", default=[f"{k}={v}" for k, v in DEFAULT.items()])
    ap.add_argument("--max-seconds", type=int, default=0, help="time limit per target (0: none)")
    args = ap.parse_args()
    runs = {k: int(v) for k, v in (x.split("=", 1) for x in args.runs)}
    # build (and check the corpus once) through the Makefile
    subprocess.run(
        ["make", "-C", str(FW), "fuzz", "FUZZ_SECONDS=1"], check=True, stdout=subprocess.DEVNULL
    )
    total, bad = 0, 0
    for name, n in runs.items():
        work = BUILD / f"corpus-{name}"
        work.mkdir(parents=True, exist_ok=True)
        t0 = time.monotonic()
        p = subprocess.run(
            [
                str(BUILD / name),
                f"-runs={n}",
                *([f"-max_total_time={args.max_seconds}"] if args.max_seconds > 0 else []),
                "-print_final_stats=1",
                f"-artifact_prefix={BUILD / name}-",
                str(work),
                str(FW / "fuzz" / "corpus" / name),
            ],
            capture_output=True,
            text=True,
        )
        text = p.stdout + p.stderr
        m = re.search(r"stat::number_of_executed_units:\s*(\d+)", text)
        execs = int(m.group(1)) if m else 0
        reports = len(re.findall(r"runtime error|ERROR: (AddressSanitizer|libFuzzer)", text))
        extra = [ln for ln in text.splitlines() if ln.startswith(("fuzz_can:", "fuzz_fw:"))]
        total += execs
        # 72: libFuzzer interrupted (SIGINT), with its statistics printed: not a finding
        bad += reports + (p.returncode not in (0, 72))
        print(
            f"{name}: {execs} executions in {time.monotonic() - t0:.0f} s, exit {p.returncode}, "
            f"sanitizer/fuzzer reports {reports}",
            flush=True,
        )
        for ln in extra:
            print("   ", ln, flush=True)
    print(f"total: {total} executions, {bad} findings")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
