"""Time of `pmsm-hil gap` (the diagnosis, without the emulator run) on a 2 s control-rate record.

    python benchmarks/gap_speed.py [--rig RIG] [--workers 1 2] [--record LOG.mcap]

Records a 2 s random profile (pmsm_hil.gapgen.draw) on the in-process emulator with the rig
(default profiles/rigs/lab-typical.yaml), or takes a record given with --record, then times
diagnose() on it with each number of fit processes in turn (--repeat rounds, the configurations
interleaved so that a busy quarter hour weighs on all alike) and prints the wall times, their
ratio, and whether every diagnosis gave the same result. The diagnosis pins BLAS to one thread
itself. Target (issue 10): <= 20 s."""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from pmsm_hil.gap.diagnose import diagnose
from pmsm_hil.gap.model import MotorModel
from pmsm_hil.gap.record import load_record
from pmsm_hil.gapgen.draw import SENSOR_SPEC, draw_profile
from pmsm_hil.gapgen.selftest import _write_inputs
from pmsm_hil.profiles import load_motor
from pmsm_hil.profiles._base import default_file


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rig", default=default_file("rigs/lab-typical.yaml"))
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--record", help="a control-rate record to diagnose instead of a new one")
    a = ap.parse_args()
    from pmsm_hil.gapgen.recorder import record_profile

    m = MotorModel.from_motor(load_motor(default_file("motors/paper-a-ipmsm.yaml")))
    with tempfile.TemporaryDirectory() as d:
        path = a.record
        if path is None:
            rng = np.random.default_rng(a.seed)
            prof, _ = _write_inputs(d, {}, {}, draw_profile(rng), "bench", False)
            path = os.path.join(d, "bench.mcap")
            record_profile(
                prof, path, rig_path=a.rig, seed=a.seed, full_log=False, sensors=SENSOR_SPEC
            )
        rec = load_record(path)
        times: dict[int, list[float]] = {w: [] for w in a.workers}
        results = set()
        for _ in range(a.repeat):
            for w in a.workers:
                t0 = time.perf_counter()
                res = diagnose(rec, m, workers=w)
                times[w].append(time.perf_counter() - t0)
                results.add(json.dumps(res, sort_keys=True))
    where = path if a.record else f"rig {os.path.basename(a.rig)}"
    print(f"record: {rec.n} control periods ({rec.n * rec.ts_s:.2f} s), {where}")
    print(
        f"selected: {', '.join(res['selected']) or 'none'}; results identical: {len(results) == 1}"
    )
    base = float(np.median(times[a.workers[0]]))
    for w in a.workers:
        med = float(np.median(times[w]))
        print(
            f"  {w} fit process{'es' if w > 1 else ''}: wall median {med:.1f} s, max "
            f"{max(times[w]):.1f} s over {a.repeat} runs; {base / med:.2f}x the speed of "
            f"{a.workers[0]}"
        )


if __name__ == "__main__":
    main()
