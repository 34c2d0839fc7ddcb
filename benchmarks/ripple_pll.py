"""The ripple PLL closing the loop on paper-a-sensorless.yaml (docs/sensorless.md): per plateau and
rig, the steady angle error (mean, rms), the peak through each load step, the speed estimate's
error (mean, rms), the speed tracking of the run summary, lock kept; and the start-up polarity
test over random rotor angles. Median and worst over the seeds given (tune on others).

    python3 benchmarks/ripple_pll.py --seeds 3 4 5 --rig profiles/rigs/default.yaml \
        --rig profiles/rigs/lab-typical.yaml --angles 20
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from pmsm_hil.analysis.summary import summarize_log
from pmsm_hil.device import DeviceSpec, open_device
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles import load_profile
from pmsm_hil.profiles.shipped import shipped_file
from pmsm_hil.protocol import generated as gen
from pmsm_hil.protocol.session import Session
from pmsm_hil.runner import RunOptions, run_profile

STEP_WINDOW_S = 0.3  # the transient after a load step


def run(profile, out: Path, seed: int, theta_e0_rad: float = 0.0):
    link = open_device(DeviceSpec(in_process=True, seed=seed, theta_e0_rad=theta_e0_rad), profile)
    result = run_profile(profile, Session(link), out, RunOptions(seed=seed))
    return result, read_log(str(out))


def plateau_figures(path: Path) -> list[dict]:
    """Per segment: the summary's steady window and tracking, the angle and speed-estimate errors
    there, and the peak angle error in the first STEP_WINDOW_S after a load step."""
    summary = summarize_log(path)
    log = read_log(str(path))
    t = log.topic("/pmsm/telemetry")
    ts = np.asarray(t["t_s"], float)
    err = np.angle(np.exp(1j * (t["theta_e_est_rad"] - t["theta_e_rad"])))
    d_spd = np.asarray(t["speed_est_rpm"], float) - np.asarray(t["speed_rpm"], float)
    rows = []
    for s in summary.segments:
        w0 = max(s.t_start_s, s.t_end_s - 1.0)  # the last second of the plateau
        if s.load_step_nm:
            w0 = max(w0, s.t_start_s + STEP_WINDOW_S)
        win = (ts >= w0) & (ts < s.t_end_s)
        step = (ts >= s.t_start_s) & (ts < s.t_start_s + STEP_WINDOW_S)
        rows.append(
            dict(
                name=s.name,
                setpoint_rpm=s.setpoint_rpm,
                err_mean=float(np.mean(err[win])),
                err_rms=float(np.sqrt(np.mean(err[win] ** 2))),
                err_peak=float(np.max(np.abs(err[win]))),
                step_peak=float(np.max(np.abs(err[step]))) if s.load_step_nm else None,
                spd_est_mean=float(np.mean(d_spd[win])),
                spd_est_rms=float(np.sqrt(np.mean(d_spd[win] ** 2))),
                track_err=s.mean_error_rpm,
                track_ok=bool(s.mean_ok),
                recovery_s=s.recovery_s,
            )
        )
    return rows


def polarity_trials(rig: str, n: int, seed0: int, tmp: Path) -> tuple[int, list[float]]:
    """n starts at random rotor angles: how many end on the right pole, and the final errors."""
    text = f"""name: polarity
motor: {shipped_file("motors/paper-a-ipmsm-measured.yaml")}
rig: {rig}
control: {{angle_src: ripple_pll, estimator: {{bw_rad_s: 400}}}}
telemetry: {{fast_hz: 2000, params_hz: 10, status_hz: 10, truth_hz: 100}}
segments:
  - {{name: start, duration_s: 0.3, speed_rpm: 15, ramp_rpm_s: 60, load_nm: 0}}
"""
    p = tmp / "polarity.yaml"
    p.write_text(text)
    profile = load_profile(str(p))
    rng = np.random.default_rng(seed0)
    ok, finals = 0, []
    for k in range(n):
        res, log = run(profile, tmp / f"pol{k}.mcap", seed0 + k, float(rng.uniform(0, 2 * np.pi)))
        t = log.topic("/pmsm/telemetry")
        err = np.angle(np.exp(1j * (t["theta_e_est_rad"] - t["theta_e_rad"])))
        final = float(np.max(np.abs(err[np.asarray(t["t_s"]) > 0.2])))
        ev = log.topic("/pmsm/events")
        res_pol = ev["arg"][ev["code"] == gen.ENUMS["event"]["polarity"]]
        finals.append(final)
        ok += int(res.faults == 0 and list(res_pol) in ([1], [2]) and final < 0.2)
    return ok, finals


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[3, 4, 5])
    ap.add_argument("--rig", action="append", default=None)
    ap.add_argument("--angles", type=int, default=20)
    args = ap.parse_args()
    # a rig file named relative to here is written into a profile in a temporary folder: absolute
    rigs = [str(Path(r).resolve()) if Path(r).exists() else r for r in args.rig or []] or [
        shipped_file("rigs/default.yaml"),
        shipped_file("rigs/lab-typical.yaml"),
    ]
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        for rig in rigs:
            profile = load_profile(shipped_file("paper-a-sensorless.yaml"), rig_override=rig)
            per_seed, faults = [], []
            for seed in args.seeds:
                res, _ = run(profile, tmp / f"s{seed}.mcap", seed)
                faults.append(res.faults)
                per_seed.append(plateau_figures(tmp / f"s{seed}.mcap"))
            print(
                f"\n== {Path(rig).name}: paper-a-sensorless, seeds {args.seeds}, "
                f"faults {faults} (0: lock kept)"
            )
            print(
                f"{'segment':22s} {'ang rms med/worst':>18s} {'ang mean worst':>14s} "
                f"{'step peak med/worst':>20s} {'spd est mean worst':>18s} "
                f"{'spd est rms med':>15s} {'track ok':>8s}"
            )
            for i, row in enumerate(per_seed[0]):
                col = [s[i] for s in per_seed]
                rms = [c["err_rms"] for c in col]
                mean = max((c["err_mean"] for c in col), key=abs)
                steps = [c["step_peak"] for c in col if c["step_peak"] is not None]
                step_s = f"{np.median(steps):.3f}/{max(steps):.3f}" if steps else "-"
                se_mean = max((c["spd_est_mean"] for c in col), key=abs)
                se_rms = np.median([c["spd_est_rms"] for c in col])
                ok = sum(c["track_ok"] for c in col)
                print(
                    f"{row['name']:22s} {np.median(rms):8.4f}/{max(rms):.4f} {mean:+14.4f} "
                    f"{step_s:>20s} {se_mean:+18.2f} {se_rms:15.2f} {ok:>5d}/{len(col)}"
                )
            if args.angles:
                ok, finals = polarity_trials(rig, args.angles, 1000, tmp)
                print(
                    f"polarity: right pole in {ok} of {args.angles} random rotor angles "
                    f"(final |error| median {np.median(finals):.3f}, worst {max(finals):.3f} rad)"
                )


if __name__ == "__main__":
    main()
