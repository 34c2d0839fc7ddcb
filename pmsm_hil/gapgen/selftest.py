"""`pmsm-hil gap selftest`: the blind self-test of the gap diagnosis (docs/gap.md, "Self-test").

The labels of all trials are drawn first and sealed: their SHA-256 is printed before any trial
runs. Each trial records a 2 s random profile on the in-process emulator with the hidden effects
(plus a held-out record on another random profile, and the same run without the effects for the
detectability oracle), gives the diagnoser only the control-rate log, and keeps its answer; the
scores are computed when every trial is done. Trials run on the sweep's Dask machinery
(pmsm_hil.sweep.tasks: a local cluster or a scheduler, a trial whose worker dies re-run once, and
with an output folder a journal keyed by each trial's inputs, so an interrupted self-test resumes)."""

from __future__ import annotations

import hashlib
import json
import os
import tempfile

import numpy as np
import yaml

from pmsm_hil.gapgen.draw import BASE_SENSORS, LIBRARY, SENSOR_SPEC, draw_trial, true_primary
from pmsm_hil.profiles._base import default_file

MOTOR = "motors/paper-a-ipmsm.yaml"
DETECT_REL = 0.003  # the effect changes the one-step residual MSE by this fraction of the floor
DETECT_TORQUE_REL = 0.001  # a mechanical effect's torque: this fraction of the motor's torque limit


def _write_inputs(
    d: str, trial: dict, effects: dict, segs: list, tag: str, outside: bool
) -> tuple[str, str]:
    motor = default_file(MOTOR)
    if outside:
        with open(motor) as f:
            mo = yaml.safe_load(f)
        mo["l_d_h"] *= trial["plant_l_scale"]
        mo["l_q_h"] *= trial["plant_l_scale"]
        mo["name"] = "plant"
        mo["torque_max_nm"] = 15.0  # the MTPA torque at i_max changes with the inductances
        motor = os.path.join(d, "plant-motor.yaml")
        with open(motor, "w") as f:
            yaml.safe_dump(mo, f)
    eff = {k: dict(v) for k, v in BASE_SENSORS.items()}
    for n, p in effects.items():
        p = dict(p)
        if n == "saturation":
            p["map"] = default_file("maps/paper-a-ipmsm.csv")
        eff[n] = dict(eff.get(n, {}), **p)
    rig = os.path.join(d, f"rig-{tag}.yaml")
    with open(rig, "w") as f:
        yaml.safe_dump(
            {"name": f"hidden-{tag}", "description": "sealed", "v_dc_v": None, "effects": eff}, f
        )
    prof = os.path.join(d, f"profile-{tag}.yaml")
    spec = {
        "name": f"selftest-{tag}",
        "description": "random",
        "motor": motor,
        "rig": rig,
        "control": {
            "ts_s": 50e-6,
            "rho": 1.0,
            "current_ref": "mtpa",
            "speed_loop_hz": 1000,
            "heartbeat_timeout_s": 0.5,
            "dead_time_comp": True,
        },
        "telemetry": {"fast_hz": 100, "params_hz": 10, "status_hz": 10, "truth_hz": 0},
        "segments": segs,
    }
    with open(prof, "w") as f:
        yaml.safe_dump(spec, f)
    return prof, rig


def run_trial(trial: dict) -> dict:
    """One trial in a worker: generate, diagnose (from the log only), return the answer (or the
    error, as text: a failed trial is reported, not dropped)."""
    try:
        return _run_trial(trial)
    except Exception as e:
        return {"error": f"{type(e).__name__}: {e}"}


def _run_trial(trial: dict) -> dict:
    from pmsm_hil.gap.diagnose import diagnose
    from pmsm_hil.gap.model import MotorModel
    from pmsm_hil.gap.probe import Probe
    from pmsm_hil.gap.record import load_control_record
    from pmsm_hil.gapgen.recorder import record_profile
    from pmsm_hil.profiles import load_motor

    outside = trial["kind"] == "outside"
    with tempfile.TemporaryDirectory() as d:
        logs = {}
        for tag, eff, segs, seed in (
            ("real", trial["effects"], trial["profile"], trial["seed"]),
            ("holdout", trial["effects"], trial["profile_holdout"], trial["seed"] + 1),
            ("clean", {}, trial["profile"], trial["seed"]),
        ):
            prof, rig = _write_inputs(d, trial, eff, segs, tag, outside and tag != "clean")
            path = os.path.join(d, f"{tag}.mcap")
            record_profile(prof, path, rig_path=rig, seed=seed, full_log=False, sensors=SENSOR_SPEC)
            logs[tag] = path
        m = MotorModel.from_motor(load_motor(default_file(MOTOR)))
        rec = load_control_record(logs["real"])
        res = diagnose(rec, m, holdout=load_control_record(logs["holdout"]))
        # detectability oracle (generator side): how much the hidden effects change the residual
        clean = load_control_record(logs["clean"])
        pr, pc = Probe(rec, m), Probe(clean, m)
        d_mse = float(np.mean(pr.residual() ** 2) - np.mean(pc.residual() ** 2))
        v_rel = float(np.std(rec.v_dc_v) / np.mean(rec.v_dc_v))
        n = min(rec.n, clean.n)
        d_omega = float(np.sqrt(np.mean((rec.omega_e_rad_s[:n] - clean.omega_e_rad_s[:n]) ** 2)))
    eff_out = [
        {k: e.get(k) for k in ("name", "selected", "magnitude", "interval", "closure")}
        for e in res["effects"]
    ]
    return {
        "selected": res["selected"]
        + [
            e["name"]
            for e in res["effects"]
            if e.get("selected") and e["name"] not in res["selected"]
        ],
        "selected_residual": res["selected"],
        "effects": eff_out,
        "closure": res["closure"]["closure"],
        "closure_record": res.get("closure_record", {}).get("closure"),
        "floor": res["noise_floor_v2"],
        "d_mse": d_mse,
        "v_dc_rel": v_rel,
        "d_omega": d_omega,
        "verdict": res["verdict"],
        "ambiguous": res["ambiguous"],
        "steps": res["steps"],
    }


def _hidden_torque_nm(name: str, p: dict) -> float:
    """The torque an effect adds to the machine's (rms over an electrical turn): what the torque
    balance sees. A sensor offset o makes the real current differ from the measured one by o, a
    torque ripple of 1.5 p psi_f |o| (its d-axis part is smaller on this machine)."""
    if name == "friction":
        return p["t_coulomb_nm"]
    if name == "cogging":
        return p["amplitude_nm"] / np.sqrt(2.0)
    if name == "sensor_offset":
        m = _motor()
        return m.k_t_nm_per_a * true_primary(name, p) / np.sqrt(2.0)
    return 0.0


def _motor():
    from pmsm_hil.profiles import load_motor

    return load_motor(default_file(MOTOR))


def _detectable(trial, out) -> bool:
    """dc_link: v_dc varies by > 0.2 %; friction, cogging: the hidden torque is at least
    DETECT_TORQUE_REL of the motor's torque limit; the others: the hidden effects change the one-step
    residual's MSE by at least DETECT_REL of the floor (a sensor offset: either)."""
    names = list(trial["effects"])
    if not names:
        return False
    if all(n == "dc_link" for n in names):
        return out["v_dc_rel"] > 0.002
    t_min = DETECT_TORQUE_REL * _motor().torque_max_nm
    if all(n in ("friction", "cogging") for n in names):
        return bool(max(_hidden_torque_nm(n, trial["effects"][n]) for n in names) >= t_min)
    if (
        names == ["sensor_offset"]
        and _hidden_torque_nm(names[0], trial["effects"][names[0]]) >= t_min
    ):
        return True
    return bool(out["d_mse"] > DETECT_REL * out["floor"])


def score(trials: list[dict], outs: list[dict]) -> dict:
    errors = [o["error"] for o in outs if "error" in o]
    kept = [(t, o) for t, o in zip(trials, outs, strict=False) if "error" not in o]
    trials, outs = [t for t, _ in kept], [o for _, o in kept]
    single = [(t, o) for t, o in zip(trials, outs, strict=False) if t["kind"] == "one"]
    det = [(t, o) for t, o in single if _detectable(t, o)]
    top1 = [o["selected"][:1] == list(t["effects"]) for t, o in det]
    top1_all = [o["selected"][:1] == list(t["effects"]) for t, o in single]
    two = [(t, o) for t, o in zip(trials, outs, strict=False) if t["kind"] == "two"]
    both = [set(t["effects"]) <= set(o["selected"]) for t, o in two]
    null = [o for t, o in zip(trials, outs, strict=False) if t["kind"] == "none"]
    outside = [o for t, o in zip(trials, outs, strict=False) if t["kind"] == "outside"]
    two_det = [(t, o) for t, o in two if _detectable(t, o)]
    confusion: dict[str, dict[str, int]] = {}
    for t, o in single:
        truth = next(iter(t["effects"]))
        got = o["selected"][0] if o["selected"] else "none"
        confusion.setdefault(truth, {}).setdefault(got, 0)
        confusion[truth][got] += 1
    # closure is the one-step residual's: over the trials whose residual selected an effect (the
    # views' effects - dc_link, friction, cogging, an offset seen by the torque balance - have none)
    fitted = [(t, o) for t, o in det + two_det if o.get("selected_residual", o["selected"])]
    clo = [o["closure"] for t, o in fitted]
    clo_rec = [o["closure_record"] for t, o in fitted if o.get("closure_record") is not None]
    mag_err, cover, details = [], [], []
    for t, o in zip(trials, outs, strict=False):
        details.append(
            {
                "kind": t["kind"],
                "truth": {n: true_primary(n, p) for n, p in t["effects"].items()},
                "selected": o["selected"],
                "verdict": o["verdict"],
                "closure": o["closure"],
                "closure_record": o.get("closure_record"),
                "detectable": _detectable(t, o),
                "estimates": {
                    e["name"]: [e["magnitude"], e["interval"]]
                    for e in o["effects"]
                    if e["selected"]
                },
            }
        )
    for t, o in det:
        name = next(iter(t["effects"]))
        tv = true_primary(name, t["effects"][name])
        e = next((e for e in o["effects"] if e["name"] == name and e["selected"]), None)
        if tv is None or e is None or e["magnitude"] is None:
            continue
        ref = (tv - 1.0) if name == "sensor_gain" else tv
        est = (e["magnitude"] - 1.0) if name == "sensor_gain" else e["magnitude"]
        mag_err.append(abs(est - ref) / abs(ref))
        if e.get("interval"):
            lo, hi = e["interval"]
            cover.append(lo <= tv <= hi)

    def frac(x):
        return (float(np.mean(x)), len(x)) if x else (None, 0)

    return {
        "trials": len(trials),
        "failed_trials": errors,
        "top1_detectable_single": frac(top1),
        "top1_all_single": frac(top1_all),
        "single_trials": len(single),
        "detectable_single": len(det),
        "both_found_two": frac(both),
        "false_attribution_null": frac([bool(o["selected"]) for o in null]),
        # an effect named beside the hidden ones (a null's are false attribution, above)
        "extra_effect_named": frac(
            [bool(set(o["selected"]) - set(t["effects"])) for t, o in single + two]
        ),
        "outside_flagged": frac(
            [
                (not o["selected"]) or "unexplained" in o["verdict"] or "parametric" in o["verdict"]
                for o in outside
            ]
        ),
        "parametric_flag_on_effect_trials": frac(
            ["parametric" in o["verdict"] for t, o in single + two]
        ),
        "median_closure_test_blocks": float(np.median(clo)) if clo else None,
        "median_closure_heldout_record": float(np.median(clo_rec)) if clo_rec else None,
        "median_magnitude_error": float(np.median(mag_err)) if mag_err else None,
        "worst_magnitude_error": float(np.max(mag_err)) if mag_err else None,
        "interval_coverage": frac(cover),
        "confusion": confusion,
        "details": details,
    }


def run_selftest(
    n_trials: int,
    seed: int,
    workers: int | None = None,
    progress: bool = True,
    out: str | os.PathLike | None = None,
    scheduler: str | None = None,
) -> dict:
    rng = np.random.default_rng(seed)
    trials = [draw_trial(rng) for _ in range(n_trials)]
    sealed = json.dumps(
        [{"kind": t["kind"], "effects": t["effects"], "l": t.get("plant_l_scale")} for t in trials],
        sort_keys=True,
    ).encode()
    digest = hashlib.sha256(sealed).hexdigest()
    if progress:
        print(f"labels sealed: sha256 {digest}", flush=True)
    from pathlib import Path

    from pmsm_hil.sweep.tasks import run_tasks

    outs = run_tasks(
        run_trial,
        trials,
        Path(out) if out is not None else None,
        name="selftest",
        scheduler=scheduler,
        workers=workers,
        progress=progress,
    )
    res = score(trials, outs)
    res.update(
        {
            "seed": seed,
            "labels_sha256": digest,
            "library": list(LIBRARY),
            "labels": json.loads(sealed),
            "answers": [o.get("selected", o.get("error")) for o in outs],
        }
    )
    return res


def _pct(v: float | None) -> str:
    """A relative error in percent, two significant digits (0.009 -> 0.9 %)."""
    return "-" if v is None else f"{100 * v:.2g} %"


def print_selftest(res: dict) -> None:
    def f(v):
        return "-" if v[0] is None else f"{v[0]:.0%} of {v[1]}"

    print(
        f"gap selftest: {res['trials']} trials, seed {res['seed']}, labels sha256 {res['labels_sha256']}"
    )
    for e in res["failed_trials"]:
        print(f"  failed trial: {e}")
    print(
        f"  top-1 on detectable single effects  {f(res['top1_detectable_single'])} "
        f"({res['detectable_single']} of {res['single_trials']} single trials detectable)"
    )
    print(f"  top-1 on all single effects         {f(res['top1_all_single'])}")
    print(f"  both effects found (two-effect)     {f(res['both_found_two'])}")
    print(f"  false attribution (null trials)     {f(res['false_attribution_null'])}")
    print(f"  an effect named beyond the hidden   {f(res['extra_effect_named'])}")
    print(f"  outside the library: none selected or 'unexplained'  {f(res['outside_flagged'])}")
    from pmsm_hil.gap.report import closure_text

    # a closure as the diagnosis prints it (beyond [-1, 10]: the gap is within the floor's error);
    # a magnitude error is relative to the true magnitude: in percent
    for k, text in (
        ("median_closure_test_blocks", closure_text),
        ("median_closure_heldout_record", closure_text),
        ("median_magnitude_error", _pct),
        ("worst_magnitude_error", _pct),
    ):
        v = res[k]
        name = k.replace("_", " ") + (" (relative)" if "magnitude" in k else "")
        print(f"  {name:36s} {text(v)}")
    print(
        "  (closure: the share of the gap above the noise floor that the found effects remove; "
        "above 1 when they take the residual below the floor's estimate)"
    )
    print(f"  95 % interval coverage              {f(res['interval_coverage'])}")
    print("  confusion (truth: answers)")
    for t, row in sorted(res["confusion"].items()):
        print(
            f"    {t:15s} "
            + ", ".join(f"{k} {v}" for k, v in sorted(row.items(), key=lambda kv: -kv[1]))
        )
