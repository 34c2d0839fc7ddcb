"""Scores a commissioning run on the emulator against what the plant really was (its truth and
its rig file): the errors that `pmsm-hil bench commission` tabulates and the tests bound
(docs/commissioning.md)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pmsm_hil.commission.steps import Measured
from pmsm_hil.log.reader import read_log

if TYPE_CHECKING:
    from pmsm_hil.profiles import Rig


def step_windows(log_path: Path | str) -> dict[str, tuple[float, float]]:
    """(start, end) device time of each step, from the commission_step events and results."""
    log = read_log(str(log_path))
    ev = log.topic("/pmsm/events")
    rows = log.topic("/pmsm/commission")
    starts: dict[str, float] = {}
    for kind, t, text in zip(ev["kind"], ev["t_s"], ev["text"], strict=False):
        if kind == "commission_step":
            starts[str(text).split(": ", 1)[-1]] = float(t)
    return {
        str(s): (starts.get(str(s), 0.0), float(t))
        for s, t in zip(rows["step"], rows["t_s"], strict=False)
    }


def truth_in(log_path: Path | str, t0: float, t1: float) -> dict[str, float]:
    """Mean of each /sim/truth field over [t0, t1]."""
    tr = read_log(str(log_path)).topic("/sim/truth")
    m = (tr["t_s"] >= t0) & (tr["t_s"] <= t1)
    return {k: float(np.mean(v[m])) for k, v in tr.items() if k != "t_s" and m.any()}


def commission_errors(
    log_path: Path | str, q: dict[str, Measured], rig: Rig, ts_s: float
) -> dict[str, float]:
    """Error of each commissioned quantity against the plant: absolute for the sensor offsets
    (A), the sensors' gain errors (against each channel's gain over the three's mean: the
    absolute gain is not observable) and the encoder offset (degrees electrical), relative for
    the rest."""
    win = step_windows(log_path)
    out: dict[str, float] = {}
    so = rig.effects.sensor_offset
    planted = (so.i_a_a, so.i_b_a, so.i_c_a) if so.enabled else (0.0, 0.0, 0.0)
    for ph, p in zip("abc", planted, strict=False):
        key = f"i_{ph}_offset_a"
        if key in q:
            out[f"offset_{ph}_a"] = q[key].value - p
    sg = rig.effects.sensor_gain
    gains = (sg.i_a_gain, sg.i_b_gain, sg.i_c_gain) if sg.enabled else (1.0, 1.0, 1.0)
    mean_gain = sum(gains) / 3.0  # the absolute gain is not observable: the mismatch is
    for ph, g in zip("abc", gains, strict=False):
        key = f"i_{ph}_gain_err"
        if key in q:
            out[f"gain_{ph}"] = q[key].value - (g / mean_gain - 1.0)
    if "enc_offset_delta_e_rad" in q:
        enc = rig.effects.encoder
        true_fw = -(enc.offset_e_rad if enc.enabled else 0.0)  # what the firmware must add
        d = q["enc_offset_delta_e_rad"].value - true_fw
        out["enc_offset_deg"] = math.degrees(math.atan2(math.sin(d), math.cos(d)))
    if "v_dist_plateau_v" in q:
        dt = rig.effects.dead_time
        if dt.enabled:
            true_v = q["v_dc_ref_v"].value * dt.dead_time_s / ts_s + dt.v_drop_v
            out["plateau_rel"] = q["v_dist_plateau_v"].value / true_v - 1.0
            if "v_drop_v" in q:
                v_dt = q["v_dist_plateau_v"].value - q["v_drop_v"].value
                true_dt = q["v_dc_ref_v"].value * dt.dead_time_s / ts_s
                out["dead_time_rel"] = v_dt / true_dt - 1.0
                out["v_drop_v"] = q["v_drop_v"].value - dt.v_drop_v
    if "r_s_ohm" in q and "r_s" in win:
        t = truth_in(log_path, *win["r_s"])
        out["r_rel"] = q["r_s_ohm"].value / t["r_s_ohm"] - 1.0
    if "l_d_h" in q and "l_dq" in win:
        t0, t1 = win["l_dq"]
        # the d test runs in the first half of the step's pulses, the q test in the second
        mid = t0 + 0.5 * (t1 - t0)
        td, tq = truth_in(log_path, t0, mid), truth_in(log_path, mid, t1)
        out["l_d_rel"] = q["l_d_h"].value / td["l_d_h"] - 1.0
        out["l_q_rel"] = q["l_q_h"].value / tq["l_q_h"] - 1.0
    if "psi_f_wb" in q and "psi_f" in win:
        t = truth_in(log_path, *win["psi_f"])
        out["psi_f_rel"] = q["psi_f_wb"].value / t["psi_f_wb"] - 1.0
    return out
