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


def failure_text(
    step: str, why: str, row: dict | None = None, pole_pairs: int = 0, enc_lines: int = 0
) -> str:
    """What stopped the sequence and what to check; with the failed step's result ``row`` (its
    values as measured), the motor file's ``pole_pairs`` and the rig's encoder lines, what the
    measurement says about the cause (failure_detail)."""
    hint = FAILURE_HINTS.get((step, why)) or FAILURE_HINTS.get((None, why)) or why
    detail = failure_detail(step, why, row, pole_pairs, enc_lines) if row else ""
    return f"commissioning stopped in step {step} ({STEP_TITLES.get(step, step)}): {why.replace('_', ' ')}: {hint}{detail}"


def failure_detail(step: str, why: str, row: dict, pole_pairs: int, enc_lines: int) -> str:
    """The failed encoder step's numbers, for the two failures whose cause they tell: the field
    turn seen as other than one encoder turn (which pole_pairs or line count would fit), and
    offset samples that scatter (a test current too weak against friction and cogging lags the
    rotor behind the field); "" otherwise."""
    if step != "encoder":
        return ""
    q = step_quantities(row)
    turns = q["turns_per_field_turn"].value
    if why == "pole_pairs" and abs(turns) > 1e-6:
        p_fit, lines_fit = pole_pairs / turns, enc_lines * turns
        return (
            f" (the encoder turned {turns:.3g} electrical turns per field turn: with the rig's "
            f"{enc_lines}-line encoder the motor has pole_pairs {p_fit:.3g}, not the motor file's "
            f"{pole_pairs}; with {pole_pairs} pole pairs the encoder has {lines_fit:.4g} lines, "
            f"not the rig's encoder.lines {enc_lines})"
        )
    if why == "not_repeatable":
        std_deg = math.degrees(q["enc_offset_delta_e_rad"].spread)
        lag_deg = math.degrees(abs(q["friction_lag_e_rad"].value))
        return (
            f" (the offset samples scatter by {std_deg:.2g} deg electrical, more than the step "
            f"accepts; the rotor lags the field by {lag_deg:.2g} deg: "
            "a test current too weak against friction and cogging leaves the rotor where they "
            "hold it; a larger --i-test, up to the motor file's i_max_a, pulls it harder)"
        )
    return ""


# below 6 i_dt the phase currents are not all past the inverter's knee and its distortion stays
# in R (the firmware's R step aims its lower level there, within its test current)
R_KNEE_MULT = 6.0


def r_knee_warning(rows: list[dict], quantities: dict[str, Measured]) -> str:
    """A warning when the R step ran its lower level under 6 i_dt (a test current too small
    against the inverter's knee: R came out +0.5 % at 4.5 i_dt and +2 % at 3.6 i_dt on a 48 V
    servo, docs/commissioning.md); "" otherwise."""
    r_row = next((r for r in rows if r["step"] == "r_s" and r["status"] == "ok"), None)
    if r_row is None or "i_dt_a" not in quantities:
        return ""
    i_dt = quantities["i_dt_a"].value
    i_lo, i_hi = abs(r_row["ref_0"]), abs(r_row["ref_1"])
    if i_lo >= R_KNEE_MULT * i_dt * 0.999:
        return ""
    return (
        f"R was measured at {i_lo:.3g} A and {i_hi:.3g} A, the lower under 6 x the inverter's "
        f"current band i_dt {i_dt:.3g} A = {R_KNEE_MULT * i_dt:.3g} A: the inverter's distortion "
        f"is not all past its knee there and R may be a few % high; commission with --i-test "
        f"{i_hi * R_KNEE_MULT * i_dt / i_lo:.3g} A or more if the motor allows (its i_max_a)"
    )


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
            "v_dc_lowest_v": Measured(v[1], 0.0, "V"),  # not the motor file's trip limits
            "v_dc_highest_v": Measured(v[2], 0.0, "V"),
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
