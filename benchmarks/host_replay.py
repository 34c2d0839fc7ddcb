"""The host's part of a run, alone: paper-a's link octets, recorded once from the emulator in
process, replayed through the frame decoder, the recorder and the log writer (journal on, as in
`pmsm-hil run`) in reads of a given size; CPU time per frame, median of repeats. With ``--base DIR``
another source tree's host (its own decoder, recorder and writer, this tree's octets) is measured
interleaved, each in a fresh process, and the ratio printed per pair.

    nice python3 benchmarks/host_replay.py [--repeat 5] [--read 4095] [--base DIR]

Reads of 4095 octets are what a pty hands over at once; with the serial transport gathering reads
(pmsm_hil/transport/serial_port.py) a run's receive batches are larger, so the figure for 4095 is
the host's cost at its worst batch size.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# runs in a fresh interpreter with the tree to measure first on sys.path
_REPLAY = r"""
import json, os, sys, time
sys.path.insert(0, sys.argv[1])
from pmsm_hil.log.writer import LogWriter
from pmsm_hil.protocol.codec import FrameDecoder
from pmsm_hil.recorder import Recorder
data = open(sys.argv[2], "rb").read()
step, out = int(sys.argv[3]), sys.argv[4]
w = LogWriter(out, {"run": {}}, wall_start_s=0.0, flush_wall_s=0.25, journal=True)
rec = Recorder(w, 50e-6, ["segment"])
dec = FrameDecoder()
c0, t0, n = time.process_time(), time.perf_counter(), 0
for at in range(0, len(data), step):
    frames = dec.feed(data[at : at + step])
    n += len(frames)
    if frames:
        rec.frames(frames)
w.close()
print(json.dumps({"cpu_s": time.process_time() - c0, "wall_s": time.perf_counter() - t0,
                  "frames": n, "log_octets": os.path.getsize(out)}))
"""


def record_octets(path: str, seed: int = 1) -> None:
    """paper-a's UART octets from the emulator in this process (heartbeats as the host sends)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from emulator_speed import start_inproc

    from pmsm_hil.profiles import load_profile

    dev, s = start_inproc(load_profile(str(ROOT / "profiles" / "paper-a.yaml")), seed)
    out, ticks = [], 0
    while dev.active:
        n, octets = dev.run(1000)
        ticks += n
        out.append(octets)
        s.send("heartbeat", counter=ticks)
    with open(path, "wb") as f:
        f.write(b"".join(out))


def replay(tree: Path, octets: str, step: int, log: str) -> dict:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    res = subprocess.run(
        [sys.executable, "-c", _REPLAY, str(tree), octets, str(step), log],
        capture_output=True,
        text=True,
        check=True,
        env=env,
    )
    return json.loads(res.stdout)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--read", type=int, default=4095, help="octets per read (default 4095)")
    ap.add_argument("--base", default=None, help="another source tree, measured interleaved")
    args = ap.parse_args()
    trees = {"this tree": ROOT}
    if args.base:
        trees["base"] = Path(args.base).resolve()
    with tempfile.TemporaryDirectory() as d:
        octets = os.path.join(d, "paper-a.octets")
        record_octets(octets)
        print(f"paper-a's link octets: {os.path.getsize(octets):,} (seed 1), reads of {args.read}")
        runs: dict[str, list[dict]] = {k: [] for k in trees}
        for tree in trees.values():  # once each first: byte-code caches written, files warm
            replay(tree, octets, args.read, os.path.join(d, "warm.mcap"))
        for _ in range(args.repeat):
            for name, tree in trees.items():
                runs[name].append(replay(tree, octets, args.read, os.path.join(d, "r.mcap")))
    for name, rs in runs.items():
        cpu = statistics.median(r["cpu_s"] for r in rs)
        n = rs[0]["frames"]
        print(
            f"{name}: {n} frames, CPU median {cpu * 1e3:.0f} ms = {cpu / n * 1e6:.2f} us per frame "
            f"(worst {max(r['cpu_s'] for r in rs) / n * 1e6:.2f}), log {rs[0]['log_octets']:,} "
            f"octets"
        )
    if "base" in runs:
        ratios = [
            b["cpu_s"] / a["cpu_s"] for a, b in zip(runs["this tree"], runs["base"], strict=True)
        ]
        print(
            f"base / this tree, CPU per pair: {', '.join(f'{r:.2f}' for r in ratios)} "
            f"(median {statistics.median(ratios):.2f}x)"
        )


if __name__ == "__main__":
    main()
