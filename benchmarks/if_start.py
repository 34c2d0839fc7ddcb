"""The MRAS's current-frequency start on profiles/paper-b-start.yaml (docs/sensorless.md): from
random rotor angles at rest, per rig: how many starts reach the 600 r/min plateau without a fault,
the speed at which the MRAS took over, the time to reach 590 r/min, the angle error against the
encoder in the 0.1 s after the handover (peak) and from 0.3 s after it to the end (rms).

    python3 benchmarks/if_start.py --angles 20 --seed 7
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from pmsm_hil.device import DeviceSpec, open_device
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles import load_profile
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import RunOptions, run_profile

ROOT = Path(__file__).resolve().parents[1]
RIGS = ("default", "lab-typical")


def once(profile, seed: int, theta0: float, out: Path) -> dict | str:
    link = open_device(DeviceSpec(in_process=True, seed=seed, theta_e0_rad=theta0), profile)
    try:
        res = run_profile(profile, Session(link), out, RunOptions(seed=seed))
    finally:
        link.close()
    if res.state != "done" or res.faults:
        return f"theta0 {theta0:+.2f}: {res.state} {res.stop_reason}"
    log = read_log(out)
    ev = log.topic("/pmsm/events")
    hand = [
        (float(t), int(a))
        for t, k, a in zip(ev["t_s"], ev["kind"], ev["arg"], strict=True)
        if str(k) == "if_handover"
    ]
    if not hand:
        return f"theta0 {theta0:+.2f}: no handover"
    t_h, arg = hand[0]
    tel = log.topic("/pmsm/telemetry")
    t = np.asarray(tel["t_s"])
    err = np.angle(
        np.exp(1j * (np.asarray(tel["theta_e_est_rad"]) - np.asarray(tel["theta_e_rad"])))
    )
    spd = np.asarray(tel["speed_rpm"])
    reach = t[np.argmax(spd >= 590.0)] if np.any(spd >= 590.0) else np.nan
    tr = (t >= t_h) & (t < t_h + 0.1)
    st = (t >= t_h + 0.3) & (t < t[-1] - 0.35)  # to the ramp down at the end
    return dict(
        handover_rpm=arg / 10.0,
        reach_s=float(reach),
        peak_rad=float(np.max(np.abs(err[tr]))),
        rms_rad=float(np.sqrt(np.mean(err[st] ** 2))),
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--angles", type=int, default=20)
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    angles = rng.uniform(-np.pi, np.pi, args.angles)
    print(f"I/f start, {args.angles} random rotor angles (seed {args.seed}); median / worst")
    with tempfile.TemporaryDirectory() as d:
        for rig in RIGS:
            profile = load_profile(
                ROOT / "profiles" / "paper-b-start.yaml",
                rig_override=ROOT / "profiles" / "rigs" / f"{rig}.yaml",
            )
            rows, failed = [], []
            for k, th in enumerate(angles):
                r = once(profile, 1000 + k, float(th), Path(d) / f"{rig}-{k}.mcap")
                (failed if isinstance(r, str) else rows).append(r)
            print(f"{rig}: {len(rows)}/{len(angles)} started")
            for key, unit in (
                ("handover_rpm", "r/min"),
                ("reach_s", "s"),
                ("peak_rad", "rad"),
                ("rms_rad", "rad"),
            ):
                v = np.array([r[key] for r in rows])
                print(f"  {key:<13} {np.median(v):8.4g} / {v.max():8.4g} {unit}")
            for f in failed:
                print("   failed:", f)


if __name__ == "__main__":
    main()
