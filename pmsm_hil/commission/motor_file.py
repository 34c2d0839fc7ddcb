"""From the nominal motor file and the commissioning results to a commissioned motor file: the
measured values replace the nominal ones the firmware uses, the calibrations are added, and the
`commissioning` record keeps every quantity with its spread, the date, the device and the
nominal values (docs/commissioning.md)."""

from __future__ import annotations

import datetime as _dt
import math
import os
import re
from typing import Any

import yaml

from pmsm_hil.commission.steps import Measured
from pmsm_hil.profiles.motor import Motor, mtpa_torque_nm

# the machine values a commissioned file replaces; the nominal ones are kept in the record
NOMINAL_KEYS = ("r_s_ohm", "l_d_h", "l_q_h", "psi_f_wb", "dead_time_s", "v_drop_v", "i_dt_a")


def _wrap_pi(x: float) -> float:
    return math.atan2(math.sin(x), math.cos(x))


def commissioned_values(motor: Motor, q: dict[str, Measured], ts_s: float) -> dict[str, Any]:
    """The motor-file fields that commissioning measured (only those of the steps that ran)."""
    out: dict[str, Any] = {}
    if "r_s_ohm" in q:
        out["r_s_ohm"] = q["r_s_ohm"].value
    if "l_d_h" in q:
        out["l_d_h"] = q["l_d_h"].value
        out["l_q_h"] = q["l_q_h"].value
    if "psi_f_wb" in q:
        out["psi_f_wb"] = q["psi_f_wb"].value
    if "v_dist_plateau_v" in q:
        plateau, v_dc = q["v_dist_plateau_v"].value, q["v_dc_ref_v"].value
        # the staircase under clamped PWM splits the plateau into device drop and dead time (a log
        # from before that: the motor file's drop)
        drop = min(float(q["v_drop_v"].value if "v_drop_v" in q else motor.v_drop_v), plateau)
        out["dead_time_s"] = max(plateau - drop, 0.0) * ts_s / v_dc if v_dc > 0 else 0.0
        out["v_drop_v"] = drop
        out["i_dt_a"] = q["i_dt_a"].value
    if "enc_offset_delta_e_rad" in q:
        out["enc_offset_e_rad"] = _wrap_pi(
            float(motor.enc_offset_e_rad) + q["enc_offset_delta_e_rad"].value
        )
    sensors: dict[str, float] = {}
    old = motor.current_sensors
    for ph in "abc":
        key = f"i_{ph}_offset_a"
        if key in q:
            sensors[key] = (getattr(old, key) if old else 0.0) + q[key].value
        gkey = f"i_{ph}_gain_err"
        if gkey in q:
            g0 = getattr(old, gkey) if old else 0.0
            sensors[gkey] = (1.0 + g0) * (1.0 + q[gkey].value) - 1.0
    if sensors:
        out["current_sensors"] = sensors
    return out


def commissioned_motor_yaml(
    motor: Motor,
    q: dict[str, Measured],
    ts_s: float,
    device: str,
    log_path: str,
    now: _dt.datetime | None = None,
    out_dir: str | None = None,
) -> str:
    """The text of the commissioned motor file, to be written in `out_dir` (default: the working
    directory): a flux map named relative to the nominal file is named relative to that."""
    raw = yaml.safe_load(motor.yaml_text) or {}
    map_path = motor.flux_map_path()
    if map_path and not os.path.isabs(str(raw.get("flux_map", ""))):
        raw["flux_map"] = os.path.relpath(map_path, out_dir or os.getcwd()).replace("\\", "/")
    prev = raw.get("commissioning") if isinstance(raw.get("commissioning"), dict) else None
    nominal = dict(prev["nominal"]) if prev and isinstance(prev.get("nominal"), dict) else {}
    for k in NOMINAL_KEYS:
        nominal.setdefault(k, raw.get(k, getattr(motor, k)))
    new = commissioned_values(motor, q, ts_s)
    out = dict(raw)
    for k, v in new.items():
        if k == "current_sensors":
            merged = dict(out.get("current_sensors") or {})
            merged.update({kk: float(vv) for kk, vv in v.items()})
            out[k] = merged
        else:
            out[k] = float(v)
    # the torque limit must stay within what i_max gives with the measured parameters
    t_mtpa = mtpa_torque_nm(
        float(out["i_max_a"]),
        int(out["pole_pairs"]),
        float(out["psi_f_wb"]),
        float(out["l_d_h"]),
        float(out["l_q_h"]),
    )
    if float(out["torque_max_nm"]) > t_mtpa:
        out["torque_max_nm"] = float(f"{t_mtpa * 0.999:.4g}")
    stamp = (now or _dt.datetime.now(_dt.UTC)).strftime("%Y-%m-%dT%H:%M:%SZ")
    out["name"] = f"{raw.get('name', motor.name)}-commissioned"
    out["commissioning"] = {
        "date": stamp,
        "device": device,
        "log": log_path,
        "nominal_file": motor.path.replace("\\", "/").rsplit("/", 1)[-1],
        "nominal": {k: float(v) for k, v in nominal.items()},
        "measured": {
            k: {"value": float(m.value), "spread": float(m.spread), "unit": m.unit}
            for k, m in q.items()
        },
    }
    head = (
        f"# Commissioned by `pmsm-hil commission` on {stamp} ({device}).\n"
        f"# The machine values and calibrations below are measured; `commissioning` keeps each\n"
        f"# measured quantity with its spread and the nominal values (docs/commissioning.md).\n"
    )
    return head + yaml.safe_dump(out, sort_keys=False, width=100)


def with_flux_map(text: str, csv_name: str, record: dict[str, Any]) -> str:
    """The commissioned motor file's text with its measured flux map named (`flux_map`, relative
    to the motor file) and the measurement recorded under `commissioning.flux_map`."""
    head = "".join(line + "\n" for line in text.splitlines() if line.startswith("#"))
    data = yaml.safe_load(text) or {}
    comm = data.setdefault("commissioning", {})
    # the emulator's plant keeps the nominal machine's magnetics (None: linear)
    comm.setdefault("nominal", {}).setdefault("flux_map", data.get("flux_map"))
    data["flux_map"] = csv_name
    comm["flux_map"] = record
    return head + yaml.safe_dump(data, sort_keys=False, width=100)


def other_rig_warning(motor: Motor, rig_name: str) -> str | None:
    """A warning when a motor file commissioned on the emulator with one rig runs on another: its
    encoder offset, sensor calibration and inverter model are the other rig's (a walk's file
    commissioned on a rig with its encoder 1 rad off ran on lab-typical into over_speed within
    0.09 s, with nothing to say why). None when the rigs' names agree or the device was no
    emulator (a rig's port names nothing to compare)."""
    device = str((motor.commissioning or {}).get("device", ""))
    m = re.fullmatch(r"emulator, rig (.+), seed \d+", device)
    if not m or m.group(1) == rig_name:
        return None
    return (
        f"{motor.path}: commissioning.device = '{device}': this run's rig is {rig_name}, not "
        f"{m.group(1)}; the file's enc_offset_e_rad, current_sensors and inverter model are "
        f"{m.group(1)}'s (commission on {rig_name}: pmsm-hil commission --rig {rig_name} -o FILE)"
    )
