"""The fast telemetry's u_d, u_q are the mean of the voltage applied over the frame's interval
(firmware/core/fw_msg.c), not one period's: under the MPCC a period's voltage is one of eight
vectors, hundreds of volts apart, and a sample of one period in ten aliases the switching (two
runs of one rig differed by 7 and 15 V rms in their segments' settled means)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from pmsm_hil.gap.model import rot_cs
from pmsm_hil.gap.record import load_record
from pmsm_hil.gapgen.recorder import record_profile
from pmsm_hil.gapgen.verify import _plateau_means, _segment_bounds
from pmsm_hil.log.reader import read_log

ROOT = Path(__file__).resolve().parents[1]
PROFILE = ROOT / "tests/data/gap-short.yaml"
RIG = ROOT / "profiles/rigs/lab-typical.yaml"


def _run(tmp_path: Path, seed: int):
    out = tmp_path / f"run{seed}.mcap"
    record_profile(PROFILE, out, rig_path=RIG, seed=seed, full_log=True)
    log = read_log(out)
    tel = log.topic("/pmsm/telemetry")
    spec = yaml.safe_load(PROFILE.read_text())
    bounds = _segment_bounds(
        log, float(tel["t_s"][-1]), [g["duration_s"] for g in spec["segments"]]
    )
    return out, tel, bounds


def test_the_telemetry_carries_the_intervals_mean_voltage(tmp_path):
    out1, tel1, bounds = _run(tmp_path, 1)
    _, tel2, _ = _run(tmp_path, 2)
    # two noise seeds of one rig: the settled voltages agree (a sample per frame: volts apart)
    for s in ("u_d_v", "u_q_v"):
        a = _plateau_means(tel1["t_s"], tel1[s], bounds)
        b = _plateau_means(tel2["t_s"], tel2[s], bounds)
        assert np.all(np.isfinite(a)) and np.sqrt(np.mean((a - b) ** 2)) < 0.5, (s, a - b)
    # each frame is the mean over its interval: its frame-to-frame scatter is far below that of
    # the single periods' vectors (the control-rate record's, in dq)
    rec = load_record(out1)
    th = rec.theta_e_rad
    u = rot_cs(rec.u_alpha_beta(), np.cos(th), -np.sin(th))
    a, b = bounds[-1]
    k = (rec.t_s >= a) & (rec.t_s < b)
    j = (tel1["t_s"] >= a) & (tel1["t_s"] < b)
    for col, s in enumerate(("u_d_v", "u_q_v")):
        assert np.std(tel1[s][j]) < 0.5 * np.std(u[k, col]), s
        assert abs(np.mean(tel1[s][j]) - np.mean(u[k, col])) < 0.1 * np.std(u[k, col]), s
