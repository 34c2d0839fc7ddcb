"""`pmsm-hil gap verify LOG --rig fitted-rig.yaml`: end-to-end closure. The log's own profile (its
`profile.yaml` and `motor.yaml` attachments) is re-run on the emulator twice, with the nominal model
(`rigs/ideal.yaml`) and with the fitted rig; the free run of both is compared with the log's,
smoothed over 5 ms so that sensor noise and switching ripple, which no model reproduces sample by
sample, do not count, and each segment's settled half by its mean (docs/gap.md, "How far").

The dq currents and voltages come from the continuous control-rate recording when the log holds one
(a `gap record` log; the re-runs always do): every period, the voltage from the switch states or
duties and the DC link at the period's mid angle. Firmware builds before the telemetry carried
each interval's mean voltage sent one period's in ten, of a finite-control-set voltage switching by
hundreds of volts, whose aliases moved a segment's mean u_d by up to 17 V between two runs of the
same rig; the telemetry is used for a log without the recording (and always for the speed)."""

from __future__ import annotations

import os
import tempfile

import numpy as np
import yaml

from pmsm_hil.gap.model import abc_to_ab, rot_cs
from pmsm_hil.gap.record import CONTROL_TOPIC, ControlRecord, record_from_log
from pmsm_hil.gapgen.recorder import record_profile
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles._base import default_file

SIGNALS = ("speed_rpm", "i_d_a", "i_q_a", "u_d_v", "u_q_v")
SMOOTH_S = 5e-3


def _smooth(t, x, t_grid):
    """The 5 ms moving mean of x (NaN samples left out) at the times t_grid."""
    dt = np.median(np.diff(t)) if len(t) > 1 else 1.0
    n = max(round(SMOOTH_S / dt), 1)
    k = np.ones(n) / n
    ok = np.isfinite(x)
    cnt = np.convolve(ok.astype(float), k, mode="same")
    with np.errstate(invalid="ignore", divide="ignore"):
        xs = np.convolve(np.where(ok, x, 0.0), k, mode="same") / cnt
    good = np.isfinite(xs)
    return np.interp(t_grid, t[good], xs[good]) if good.any() else np.full(len(t_grid), np.nan)


def _series(log, path, control: bool = True) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each signal's (t_s, values): the dq currents and voltages at the control rate when
    ``control`` and the log holds the continuous recording, else (and the speed always) the
    telemetry's."""
    tel = log.topic("/pmsm/telemetry")
    out = {s: (np.asarray(tel["t_s"], float), np.asarray(tel[s], float)) for s in SIGNALS}
    if not control or CONTROL_TOPIC not in log.topics:
        return out
    rec = record_from_log(log, path)
    if not isinstance(rec, ControlRecord) or rec.n < 2:
        return out
    th = rec.theta_e_rad
    i_dq = rot_cs(abc_to_ab(rec.i_abc), np.cos(th), -np.sin(th))
    mid = th + 0.5 * rec.omega_e_rad_s * rec.ts_s  # the voltage acts over the period
    u_dq = rot_cs(rec.u_alpha_beta(), np.cos(mid), -np.sin(mid))
    u_dq[~rec.pwm_on] = np.nan  # no voltage is applied: not a sample of the model's
    for j, (i_name, u_name) in enumerate((("i_d_a", "u_d_v"), ("i_q_a", "u_q_v"))):
        out[i_name] = (rec.t_s, i_dq[:, j])
        out[u_name] = (rec.t_s, u_dq[:, j])
    return out


def verify(log_path: str | os.PathLike, rig_path: str | os.PathLike, seed: int = 1) -> dict:
    log = read_log(log_path)
    att = {a.name: a.data for a in log.attachments}
    if "profile.yaml" not in att or "motor.yaml" not in att:
        raise ValueError(
            f"{log_path}: the log carries no profile.yaml/motor.yaml to re-run (a `pmsm-hil run` log)"
        )
    real = log.topic("/pmsm/telemetry")
    if not len(real["t_s"]):
        raise ValueError(f"{log_path}: no /pmsm/telemetry to compare against")
    signals: dict[str, dict[str, float]] = {}
    out: dict[str, object] = {"signals": signals}
    with tempfile.TemporaryDirectory() as d:
        motor = os.path.join(d, "motor.yaml")
        with open(motor, "wb") as f:
            f.write(att["motor.yaml"])
        spec = yaml.safe_load(att["profile.yaml"])
        spec["motor"] = motor
        spec.pop("rig", None)
        prof = os.path.join(d, "profile.yaml")
        with open(prof, "w") as f:
            yaml.safe_dump(spec, f)
        runs = {}
        stopped: dict[str, dict[str, object]] = {}
        out["stopped_early"] = stopped
        control = CONTROL_TOPIC in log.topics  # the re-runs are read as the log is
        for tag, rig in (
            ("nominal", default_file("rigs/ideal.yaml")),
            ("fitted", os.fspath(rig_path)),
        ):
            path = os.path.join(d, f"{tag}.mcap")
            record_profile(prof, path, rig_path=rig, seed=seed, full_log=True)
            rerun = read_log(path)
            runs[tag] = _series(rerun, path, control)
            stop = _early_stop(rerun)
            if stop:  # compared up to there only: said, or the scores read as a poor fit
                stopped[tag] = stop
    ours = _series(log, log_path)
    t = np.asarray(real["t_s"], float)  # the comparison's grid: the log's telemetry times
    for s in SIGNALS:
        ref = _smooth(*ours[s], t)
        signals[s] = _score(*(_smooth(*runs[tag][s], t) - ref for tag in ("nominal", "fitted")))
    cl = [v["closure"] for k, v in signals.items() if k != "speed_rpm"]
    out["closure_median"] = float(np.median(cl))
    # the same on each segment's settled half (its mean): what a steady-state comparison sees,
    # free of the switching pattern and of the speed loop's noise, which no two runs share
    segs = spec.get("segments") or []
    durations = (
        [float(g["duration_s"]) for g in segs] if all("duration_s" in g for g in segs) else None
    )
    bounds = _segment_bounds(log, float(t[-1]), durations)
    plateau: dict[str, dict[str, float]] = {}
    for s in SIGNALS:
        ref = _plateau_means(*ours[s], bounds)
        plateau[s] = _score(
            *(_plateau_means(*runs[tag][s], bounds) - ref for tag in ("nominal", "fitted"))
        )
    out["plateau"] = plateau
    out["plateau_closure_median"] = float(
        np.median([v["closure"] for k, v in plateau.items() if k != "speed_rpm"])
    )
    return out


def _early_stop(log) -> dict[str, object] | None:
    """How a re-run ended when not at its profile's end: {"t_s", "why"} (a fault, e.g. a fitted
    rig whose plant cannot carry the profile's load: over_current), else None."""
    if "/pmsm/events" not in log.topics:
        return None
    ev = log.topic("/pmsm/events")
    for t, kind, text in zip(ev["t_s"], ev["kind"], ev["text"], strict=True):
        if kind == "stopped" and "profile end" not in str(text):
            return {"t_s": float(t), "why": str(text)}
    return None


def _score(err_nominal: np.ndarray, err_fitted: np.ndarray) -> dict[str, float]:
    """Both models' rms errors against the log (NaN left out) and the closure 1 - MSE_f / MSE_n."""
    mb, ma = float(np.nanmean(err_nominal**2)), float(np.nanmean(err_fitted**2))
    return {
        "rms_nominal": float(np.sqrt(mb)),
        "rms_fitted": float(np.sqrt(ma)),
        "closure": (mb - ma) / mb if mb > 0 else 0.0,
    }


def _segment_bounds(
    log, t_end: float, durations: list[float] | None = None
) -> list[tuple[float, float]]:
    """(start, end) of each segment's second half, from the log's segment_start events; a segment
    ends at the next one's start or, given the profile's ``durations``, after its own duration (the
    last one is not followed into the stop after the profile)."""
    ev = log.topic("/pmsm/events") if "/pmsm/events" in log.topics else {"t_s": [], "kind": []}
    starts = [
        float(ts) for ts, k in zip(ev["t_s"], ev["kind"], strict=True) if k == "segment_start"
    ]
    ends = [*starts[1:], t_end]
    if durations is not None and len(durations) >= len(starts):
        ends = [min(b, a + float(d)) for a, b, d in zip(starts, ends, durations, strict=False)]
    return [(a + 0.5 * (b - a), b) for a, b in zip(starts, ends, strict=True) if b > a]


def _plateau_means(t, x, bounds) -> np.ndarray:
    t, x = np.asarray(t, float), np.asarray(x, float)
    out = []
    for a, b in bounds:
        v = x[(t >= a) & (t < b)]
        v = v[np.isfinite(v)]
        out.append(float(np.mean(v)) if len(v) else np.nan)
    return np.array(out)
