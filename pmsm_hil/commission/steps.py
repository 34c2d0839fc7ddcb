"""What each commissioning step reports (the firmware's commission_result values) and what a
failure means for the person at the rig (docs/commissioning.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pmsm_hil.log.reader import Log

STEP_TITLES = {
    "offsets": "current-sensor offsets (PWM off)",
    "v_dc": "DC-link voltage",
    "encoder": "encoder offset by d-axis alignment (direction, pole pairs, sensor gains)",
    "inverter": "inverter distortion: dead time and device drop (standstill staircases, SVPWM and clamped)",
    "r_s": "stator resistance by injection",
    "l_dq": "L_d and L_q at standstill (voltage pulses)",
    "psi_f": "psi_f by a short spin",
}

# (step, failure) -> what to check; (None, failure) for any step
FAILURE_HINTS = {
    (None, "no_current"): "no current flows although a voltage is applied: check the motor "
    "cables and the phase connections, and that the inverter is enabled",
    (None, "wrong_direction"): "the rotor turns against the field: two motor phases are swapped "
    "(or the encoder counts backwards); swap two phases or the encoder's A/B channels",
    (None, "pole_pairs"): "the encoder turned by another angle than the field: check pole_pairs in "
    "the motor file and the encoder's line count in the rig",
    (None, "rotor_stuck"): "the rotor does not follow the field: it is blocked, braked or "
    "coupled to a load that holds it",
    (None, "over_current"): "a phase current exceeded the step's limit: check for a short, and the "
    "motor file's R and L (the current loops are tuned from them)",
    (None, "over_speed"): "the spin ran away: check the encoder and the load machine",
    (None, "v_dc"): "the DC-link voltage is outside the motor file's v_dc_min_v..v_dc_max_v or "
    "ripples by more than 10 %",
    (None, "implausible"): "a result lies outside its plausible range (a sensor, wiring or "
    "motor-file problem)",
    (None, "not_repeatable"): "repeated measurements disagree: the rig is noisy or something "
    "moved during the step",
    ("offsets", "implausible"): "a current-sensor offset beyond 1 A or noise beyond 0.5 A rms: "
    "a sensor or its supply is faulty",
}


def failure_text(step: str, why: str) -> str:
    hint = FAILURE_HINTS.get((step, why)) or FAILURE_HINTS.get((None, why)) or why
    return f"commissioning stopped in step {step} ({STEP_TITLES.get(step, step)}): {why.replace('_', ' ')}: {hint}"


@dataclass
class Measured:
    """One commissioned quantity: value, spread over the step's repetitions, unit."""

    value: float
    spread: float
    unit: str

    def text(self) -> str:
        """The value with its unit, and its spread when the step repeated the measurement (a
        quantity measured once, or derived, has none: nothing is shown rather than +- 0)."""
        v, s = self.value, self.spread
        if self.unit == "rad":
            spread = f" +- {math.degrees(s):.3f} deg" if s > 0 else ""
            return f"{math.degrees(v):+.3f} deg ({v:+.5f} rad){spread}"
        return f"{v:.6g} {self.unit}".rstrip() + (f" +- {s:.2g}" if s > 0 else "")


def step_quantities(row: dict) -> dict[str, Measured]:
    """The named quantities of one /pmsm/commission row (firmware/core/comm_*.c)."""
    n = sum(1 for k in row if k.startswith("value_"))
    v = [row[f"value_{k}"] for k in range(n)]
    s = [row[f"spread_{k}"] for k in range(n)]
    step = row["step"]
    if step == "offsets":
        return {
            "i_a_offset_a": Measured(v[0], s[0], "A"),
            "i_b_offset_a": Measured(v[1], s[1], "A"),
            "i_c_offset_a": Measured(v[2], s[2], "A"),
            "i_noise_a": Measured(v[3], s[3], "A"),
        }
    if step == "v_dc":
        return {
            "v_dc_v": Measured(v[0], s[0], "V"),
            "v_dc_min_v": Measured(v[1], 0.0, "V"),
            "v_dc_max_v": Measured(v[2], 0.0, "V"),
        }
    if step == "encoder":
        ga, gb = row["ref_0"], row["ref_1"]
        return {
            "enc_offset_delta_e_rad": Measured(v[0], s[0], "rad"),
            "friction_lag_e_rad": Measured(v[1], 0.0, "rad"),
            "turns_per_field_turn": Measured(v[2], 0.0, ""),
            "i_a_gain_err": Measured(ga, 0.0, ""),
            "i_b_gain_err": Measured(gb, 0.0, ""),
            "i_c_gain_err": Measured(-(ga + gb), 0.0, ""),
        }
    if step == "inverter" and n < 5:  # a log from before the drop was measured apart
        return {
            "v_dist_plateau_v": Measured(v[0], s[0], "V"),
            "i_dt_a": Measured(v[1], s[1], "A"),
            "r_staircase_ohm": Measured(v[2], s[2], "ohm"),
            "fit_rms_v": Measured(v[3], 0.0, "V"),
            "v_dc_ref_v": Measured(row["ref_0"], 0.0, "V"),
        }
    if step == "inverter":
        return {
            "v_dist_plateau_v": Measured(v[0], s[0], "V"),
            "i_dt_a": Measured(v[1], s[1], "A"),
            "r_staircase_ohm": Measured(v[2], s[2], "ohm"),
            "v_drop_v": Measured(v[3], s[3], "V"),
            "fit_rms_v": Measured(v[4], 0.0, "V"),
            "v_dc_ref_v": Measured(row["ref_0"], 0.0, "V"),
        }
    if step == "r_s":
        return {"r_s_ohm": Measured(v[0], s[0], "ohm")}
    if step == "l_dq":
        return {
            "l_d_h": Measured(v[0], s[0], "H"),
            "l_q_h": Measured(v[1], s[1], "H"),
            "i_d_bias_a": Measured(v[2], 0.0, "A"),
        }
    if step == "psi_f":
        return {
            "psi_f_wb": Measured(v[0], s[0], "Wb"),
            "psi_f_low_speed_wb": Measured(v[1], 0.0, "Wb"),
        }
    return {}


def logged_steps(log: Log) -> list[tuple[str, str, dict[str, Measured]]]:
    """(step, status, its named quantities when ok) of each /pmsm/commission row of a log (a
    pmsm_hil.log.reader.Log), in order: what `pmsm-hil analyze` shows of a commissioning run."""
    if "/pmsm/commission" not in log.topics:
        return []
    cols = log.topic("/pmsm/commission")
    out = []
    for i in range(len(cols["step"])):
        row = {k: (v[i].item() if hasattr(v[i], "item") else v[i]) for k, v in cols.items()}
        step, status = str(row["step"]), str(row["status"])
        out.append((step, status, step_quantities(row) if status == "ok" else {}))
    return out
