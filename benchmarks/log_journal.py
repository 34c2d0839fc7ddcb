"""What the log's journal costs (docs/faults.md, "A killed host's log"): `pmsm-hil run` of a profile
(paper-a.yaml, seed 1, unpaced, the emulator child on its pty) with the journal (as shipped), without
it (the writer as before: chunks only), and with a chunk per receive batch (the other way to keep
every received message), interleaved; per variant the median over --repeat runs of the host's CPU
time, its emulator child's, the log's size and the time `read_log` takes on it, and the ratios to
"chunks only".

    nice python3 benchmarks/log_journal.py [--repeat 3] [--profile profiles/paper-a.yaml]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# the child: one run with the writer as VARIANT says, then its figures as one JSON line
CHILD = textwrap.dedent(
    """
    import json, os, resource, sys, time
    from pmsm_hil.log import writer as W
    variant = sys.argv[1]
    if variant != "journal":
        init = W.LogWriter.__init__
        def no_journal(self, *a, **k):
            k["journal"] = False
            init(self, *a, **k)
        W.LogWriter.__init__ = no_journal
        if variant == "chunk per batch":
            W.LogWriter.flush_batch = W.LogWriter.flush
    from pmsm_hil.cli.main import main
    from pmsm_hil.log.reader import read_log
    out = sys.argv[-1]
    t0 = time.process_time()
    try:
        main(sys.argv[2:])
    except SystemExit:
        pass
    host = time.process_time() - t0
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    t1 = time.process_time()
    read_log(out)
    read = time.process_time() - t1
    print(json.dumps({"host": host, "child": c.ru_utime + c.ru_stime, "octets":
                      os.path.getsize(out), "read": read}))
    """
)
VARIANTS = ("chunks only", "journal", "chunk per batch")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--profile", default=str(ROOT / "profiles" / "paper-a.yaml"))
    args = ap.parse_args()
    res: dict[str, list[dict]] = {v: [] for v in VARIANTS}
    with tempfile.TemporaryDirectory() as d:
        for _ in range(args.repeat):
            for v in VARIANTS:
                out = str(Path(d) / "run.mcap")
                cmd = [sys.executable, "-c", CHILD, v, "run", args.profile, "--seed", "1"]
                p = subprocess.run(
                    [*cmd, "--no-live", "--out", out],
                    capture_output=True,
                    text=True,
                    cwd=ROOT,
                    check=True,
                )
                res[v].append(json.loads(p.stdout.strip().splitlines()[-1]))
    base = {k: statistics.median(r[k] for r in res["chunks only"]) for k in res["chunks only"][0]}
    print(f"{Path(args.profile).name}, seed 1, {args.repeat} runs per variant (medians)")
    for v in VARIANTS:
        m = {k: statistics.median(r[k] for r in res[v]) for k in base}
        print(
            f"{v:16s} host CPU {m['host']:.3f} s ({m['host'] / base['host']:.3f}x), "
            f"host + emulator {m['host'] + m['child']:.3f} s "
            f"({(m['host'] + m['child']) / (base['host'] + base['child']):.3f}x), "
            f"log {m['octets'] / 1e6:.2f} MB ({m['octets'] / base['octets']:.3f}x), "
            f"read_log {m['read']:.3f} s ({m['read'] / base['read']:.2f}x)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
