"""Time of `pmsm-hil gap` (the diagnosis, without the emulator run) on a 2 s control-rate record.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 taskset -c 0 python benchmarks/gap_speed.py [--rig RIG]

Records a 2 s random profile (pmsm_hil.gapgen.draw) on the in-process emulator with the rig
(default profiles/rigs/lab-typical.yaml), then times diagnose() on it three times and prints the
figures: CPU time (what one core spends) and wall time (which a busy machine inflates).
Target (issue 10): <= 20 s on one core."""

from __future__ import annotations

import argparse
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
    a = ap.parse_args()
    from pmsm_hil.gapgen.recorder import record_profile

    rng = np.random.default_rng(a.seed)
    with tempfile.TemporaryDirectory() as d:
        prof, _ = _write_inputs(d, {}, {}, draw_profile(rng), "bench", False)
        path = os.path.join(d, "bench.mcap")
        record_profile(prof, path, rig_path=a.rig, seed=a.seed, full_log=False, sensors=SENSOR_SPEC)
        rec = load_record(path)
        m = MotorModel.from_motor(load_motor(default_file("motors/paper-a-ipmsm.yaml")))
        times, cpu = [], []
        for _ in range(a.repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            res = diagnose(rec, m)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
    print(
        f"record: {rec.n} control periods ({rec.n * rec.ts_s:.2f} s), rig {os.path.basename(a.rig)}"
    )
    print(
        f"gap diagnosis: CPU median {np.median(cpu):.1f} s, max {np.max(cpu):.1f} s; wall median "
        f"{np.median(times):.1f} s, max {np.max(times):.1f} s over {a.repeat} runs "
        f"(selected: {', '.join(res['selected']) or 'none'})"
    )


if __name__ == "__main__":
    main()
