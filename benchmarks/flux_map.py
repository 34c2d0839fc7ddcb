"""The flux map of `pmsm-hil commission --flux-map` against the emulator plant's map
(docs/commissioning.md): psi_d and psi_q errors at the measured operating points (rms and worst,
Wb), median and worst over the seeds given, per rig and motor.

    python3 benchmarks/flux_map.py --seeds 1 2 3 4 5 6 7 8 9 10
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import tempfile
from pathlib import Path

import numpy as np

from pmsm_hil.cli.main import main as cli_main

CASES = (("lab-typical", "paper-a-ipmsm"), ("default", "paper-a-ipmsm-measured"))
LINE = re.compile(
    r"psi_d ([\d.]+) mWb rms \(([\d.]+) worst\), psi_q ([\d.]+) mWb rms \(([\d.]+) worst\)"
)


def once(rig: str, motor: str, seed: int, work: Path) -> tuple[float, ...] | str:
    out = work / f"{rig}-{seed}.yaml"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
        code = cli_main(
            [
                "commission",
                "--rig",
                rig,
                "--motor",
                motor,
                "--seed",
                str(seed),
                "--in-process",
                "--flux-map",
                "--log",
                str(work / f"{rig}-{seed}.mcap"),
                "-o",
                str(out),
            ]
        )
    m = LINE.search(buf.getvalue())
    if code != 0 or m is None:
        return f"exit {code}: {buf.getvalue().strip().splitlines()[-1:]}"
    return tuple(float(x) for x in m.groups())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(1, 11)))
    args = ap.parse_args()
    print("flux map against the plant, mWb: median / worst over seeds", args.seeds)
    print(
        f"{'rig':<12} {'motor':<24} {'psi_d rms':>12} {'psi_d max':>12} {'psi_q rms':>12} "
        f"{'psi_q max':>12}  failed"
    )
    with tempfile.TemporaryDirectory() as d:
        for rig, motor in CASES:
            rows, failed = [], []
            for seed in args.seeds:
                r = once(rig, motor, seed, Path(d))
                (failed if isinstance(r, str) else rows).append(r)
            a = np.array(rows) if rows else np.full((1, 4), np.nan)
            cells = [f"{np.median(a[:, i]):5.2f}/{np.max(a[:, i]):5.2f}" for i in range(4)]
            print(
                f"{rig:<12} {motor:<24} " + " ".join(f"{c:>12}" for c in cells), f"  {len(failed)}"
            )
            for f in failed:
                print("   ", f)


if __name__ == "__main__":
    main()
