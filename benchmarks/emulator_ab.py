"""Two builds of the emulator's extension, paired in one process: which is faster, and by how much.

On a shared or virtual machine the wall time of one build's run moves by ±20 % from one minute to
the next, more than most changes to the loop. Here both builds run the same profile side by side
in this process, in chunks of 2000 control periods taken in turn (the order alternating), so each
pair of chunks sees the same machine; the ratio of their times is taken per pair and its median
quoted with the quartiles. Same seed, same profile: the two builds must produce the same octets
(checked; a build that changes the device data is reported as such, its timing still given).

    python3 benchmarks/emulator_ab.py OLD.so NEW.so [--rig FILE] [--repeat 2]

OLD.so / NEW.so: copies of `pmsm_hil/_fw*.so` from two builds (e.g. a `git worktree` of the older
commit, `python setup.py build_ext --inplace` there). Pin to one core (`taskset -c 1`) for the
steadiest figures.
"""

from __future__ import annotations

import argparse
import hashlib
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pmsm_hil.emulator import fwlib  # noqa: E402
from pmsm_hil.profiles import load_profile  # noqa: E402

sys.path.insert(0, str(ROOT / "benchmarks"))
from emulator_speed import start_inproc  # noqa: E402

CHUNK = 2000


def _device(so: str, profile):
    """A started emulator on the library ``so`` (fwlib loads the library PMSM_HIL_FW_LIB names)."""
    os.environ["PMSM_HIL_FW_LIB"] = so
    fwlib.lib.cache_clear()
    return start_inproc(profile)


def paired(a_so: str, b_so: str, profile, repeat: int) -> dict:
    ratios, t_a, t_b, same = [], 0.0, 0.0, True
    for _ in range(repeat):
        (da, sa), (db, sb) = _device(a_so, profile), _device(b_so, profile)
        ha, hb = hashlib.sha256(), hashlib.sha256()
        ticks, k = 0, 0
        while da.active and db.active:
            runs = [(da, sa, ha, 0), (db, sb, hb, 1)]
            dt, n = [0.0, 0.0], 0
            for d, s, h, j in runs if k % 2 == 0 else runs[::-1]:
                t0 = time.perf_counter()
                n, out = d.run(CHUNK)
                dt[j] = time.perf_counter() - t0
                h.update(out)
                s.send("heartbeat", counter=ticks + n)
            ticks += n
            k += 1
            if n == CHUNK:
                ratios.append(dt[1] / dt[0])
                t_a += dt[0]
                t_b += dt[1]
        same = same and ha.digest() == hb.digest() and da.active == db.active
    r = np.array(ratios)
    n_periods = len(r) * CHUNK
    return {
        "median": float(np.median(r)),
        "p25": float(np.percentile(r, 25)),
        "p75": float(np.percentile(r, 75)),
        "pairs": len(r),
        "total_ratio": t_b / t_a,
        "a_ns": t_a / n_periods * 1e9,
        "b_ns": t_b / n_periods * 1e9,
        "same_octets": same,
    }


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("old", help="the extension of the reference build (a .so file)")
    ap.add_argument("new", help="the extension of the build to compare (a .so file)")
    ap.add_argument("--profile", default=str(ROOT / "profiles" / "paper-a.yaml"))
    ap.add_argument(
        "--rig", action="append", default=None, help="rig file(s) (default: the profile's)"
    )
    ap.add_argument("--repeat", type=int, default=2, help="runs of the profile per rig")
    args = ap.parse_args()
    for so in (args.old, args.new):
        if not Path(so).is_file():
            sys.exit(f"error: {so}: no such file (a build's pmsm_hil/_fw*.so)")
    if Path(args.old).resolve() == Path(args.new).resolve():
        sys.exit("error: OLD and NEW are the same file: copy one build's .so elsewhere first")
    for rig in args.rig or [None]:
        profile = load_profile(args.profile, rig_override=rig)
        r = paired(args.old, args.new, profile, args.repeat)
        name = Path(rig).name if rig else "the profile's rig"
        print(
            f"{name}: new/old time per period {r['median']:.4f} median over {r['pairs']} pairs "
            f"of {CHUNK} periods (quartiles {r['p25']:.4f}-{r['p75']:.4f}; totals "
            f"{r['total_ratio']:.4f}); old {r['a_ns']:.0f} ns, new {r['b_ns']:.0f} ns per period; "
            + ("device data identical" if r["same_octets"] else "DEVICE DATA DIFFER")
        )


if __name__ == "__main__":
    main()
