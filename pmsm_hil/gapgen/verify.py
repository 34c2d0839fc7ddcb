"""`pmsm-hil gap verify LOG --rig fitted-rig.yaml`: end-to-end closure. The log's own profile (its
`profile.yaml` and `motor.yaml` attachments) is re-run on the emulator twice, with the nominal model
(`rigs/ideal.yaml`) and with the fitted rig; the free-run telemetry of both is compared with the
log's, smoothed over 5 ms so that sensor noise and switching ripple, which no model reproduces
sample by sample, do not count, and each segment's settled half by its mean (docs/gap.md, "How
far")."""

from __future__ import annotations

import itertools
import os
import tempfile

import numpy as np
import yaml

from pmsm_hil.gapgen.recorder import record_profile
from pmsm_hil.log.reader import read_log
from pmsm_hil.profiles._base import default_file

SIGNALS = ("speed_rpm", "i_d_a", "i_q_a", "u_d_v", "u_q_v")
SMOOTH_S = 5e-3


def _smooth(t, x, t_grid):
    dt = np.median(np.diff(t)) if len(t) > 1 else 1.0
    n = max(round(SMOOTH_S / dt), 1)
    k = np.ones(n) / n
    xs = np.convolve(x, k, mode="same")
    return np.interp(t_grid, t, xs)


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
        for tag, rig in (
            ("nominal", default_file("rigs/ideal.yaml")),
            ("fitted", os.fspath(rig_path)),
        ):
            path = os.path.join(d, f"{tag}.mcap")
            record_profile(prof, path, rig_path=rig, seed=seed, full_log=True)
            runs[tag] = read_log(path).topic("/pmsm/telemetry")
    t = real["t_s"]
    for s in SIGNALS:
        ref = _smooth(t, real[s], t)
        e = {tag: _smooth(r["t_s"], r[s], t) - ref for tag, r in runs.items()}
        mb, ma = float(np.mean(e["nominal"] ** 2)), float(np.mean(e["fitted"] ** 2))
        signals[s] = {
            "rms_nominal": float(np.sqrt(mb)),
            "rms_fitted": float(np.sqrt(ma)),
            "closure": (mb - ma) / mb if mb > 0 else 0.0,
        }
    cl = [v["closure"] for k, v in signals.items() if k != "speed_rpm"]
    out["closure_median"] = float(np.median(cl))
    # the same on each segment's settled half (its mean): what a steady-state comparison sees,
    # free of the switching pattern and of the speed loop's noise, which no two runs share
    bounds = _segment_bounds(log, float(t[-1]))
    plateau: dict[str, dict[str, float]] = {}
    for s in SIGNALS:
        means = {tag: _plateau_means(r["t_s"], r[s], bounds) for tag, r in runs.items()}
        ref = _plateau_means(t, real[s], bounds)
        mb = float(np.nanmean((means["nominal"] - ref) ** 2))
        ma = float(np.nanmean((means["fitted"] - ref) ** 2))
        plateau[s] = {
            "rms_nominal": float(np.sqrt(mb)),
            "rms_fitted": float(np.sqrt(ma)),
            "closure": (mb - ma) / mb if mb > 0 else 0.0,
        }
    out["plateau"] = plateau
    out["plateau_closure_median"] = float(
        np.median([v["closure"] for k, v in plateau.items() if k != "speed_rpm"])
    )
    return out


def _segment_bounds(log, t_end: float) -> list[tuple[float, float]]:
    """(start, end) of each segment's second half, from the log's segment_start events."""
    ev = log.topic("/pmsm/events") if "/pmsm/events" in log.topics else {"t_s": [], "kind": []}
    starts = [
        float(ts) for ts, k in zip(ev["t_s"], ev["kind"], strict=True) if k == "segment_start"
    ]
    edges = [*starts, t_end]
    return [(a + 0.5 * (b - a), b) for a, b in itertools.pairwise(edges) if b > a]


def _plateau_means(t, x, bounds) -> np.ndarray:
    t, x = np.asarray(t, float), np.asarray(x, float)
    return np.array(
        [
            np.mean(x[(t >= a) & (t < b)]) if np.any((t >= a) & (t < b)) else np.nan
            for a, b in bounds
        ]
    )
