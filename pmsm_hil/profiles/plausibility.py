"""Values that are legal but probably in the wrong unit (docs/profiles.md, "Plausibility
warnings"): a motor file's flux linkage, inductances and resistance against its DC link and
current limit, and a profile's speed ramps against the motor's inertia and torque limit. Each is a
warning naming file, line, field and value: the run goes ahead, as the numbers may be meant."""

from __future__ import annotations

import math

from ._base import num
from ._source import Source, fmt_num
from .motor import PSI_F_HINT, TELEMETRY_SPEED_MAX_RPM, Motor
from .sections import DEFAULT_SPEED_BW_RAD_S

# The speed's swing after a load step of dT on the speed loop (crossover bw, PI zero at bw/4, ideal
# current loop): dw(t) = (dT/J) t exp(-bw t / 2) peaks at 2/(e bw) dT/J (docs/control.md, "Speed
# loop"); the loop's delays (1 ms sampling, the encoder observer) add about a third: 5 N m stepping
# off at 450 r/min on the SEW CM3C80S (J 6e-4 kg m^2, bw 450 rad/s) swung to 624 r/min on the
# emulator, 174 r/min where the ideal loop gives 130. On three steps of that motor the swing was
# 0.99-1.07 times this estimate, so a step is warned of when 1.1 times it reaches the trip (5.5, 6
# and 7.5 N m steps at -450 r/min faulted over_speed; a 4 N m one swung to -667 r/min, a 5 N m one
# to -712, warned of; docs/control.md, tests/test_motor_plausibility.py)
LOAD_STEP_SWING = 2.0 / math.e * 1.35
LOAD_STEP_MARGIN = 1.1

# The back-EMF at the most the telemetry carries, as a share of v_dc / sqrt 3, below which psi_f_wb
# is taken for a unit slip: a motor meant for its DC link uses tens of % of it at its rated speed
# (paper A's 36 % at 1500 r/min, the 48 V servos' 75-96 %); a flux linkage 1000 x too small
# (25 mWb written as 2.5e-5) gives 0.1 %, 100 x too small 1 %.
EMF_SHARE_MIN = 0.02
# The time the DC link needs to drive i_max_a into an inductance, L i_max / (v_dc / sqrt 3), above
# which the inductance is taken for H written where mH was meant: motors take about 0.5 to 5 ms
# (paper A's L_q 0.58 ms, the 48 V servos' 1 ms), 1000 x that is seconds.
SLEW_MAX_S = 0.05
# ... and the share of a control period below which it is taken for mH written as uH (a 1000 x
# too small inductance): one period at full voltage would then move the current by ten times
# i_max_a and more. Paper A's motor at 1/8 of its inductance, which FOC still controls
# (docs/control.md), takes 0.6 of its 50 us period.
SLEW_MIN_PERIODS = 0.1
# R i_max_a over v_dc / sqrt 3 above which the resistance is taken for mohm written as ohm (1000 x
# too large). Gimbal motors are wound so that the link cannot drive i_max_a at standstill (7.5 ohm,
# 1.5 A on 12 V: 1.6 x): that is their design, not a slip; a slip gives hundreds of x.
R_DROP_MAX = 10.0


def _warn(src: Source, key: str, value: float, text: str) -> str:
    return f"{src.path}:{src.line((key,))}: {key} = {fmt_num(value)} {text}"


def motor_warnings(motor: Motor, motor_src: Source, ts_s: float | None) -> list[str]:
    """Warnings for ``motor``'s psi_f_wb, l_d_h, l_q_h and r_s_ohm against its v_dc_v and
    i_max_a (and the control period ``ts_s``, when known)."""
    out: list[str] = []
    reach_v = motor.v_dc_v / math.sqrt(3.0)
    link = f"{reach_v:.4g} V (v_dc_v {fmt_num(motor.v_dc_v)} V / sqrt 3)"
    w_top = motor.pole_pairs * TELEMETRY_SPEED_MAX_RPM * math.pi / 30.0
    emf_top_v = motor.psi_f_wb * w_top
    if emf_top_v < EMF_SHARE_MIN * reach_v:
        out.append(
            _warn(
                motor_src,
                "psi_f_wb",
                motor.psi_f_wb,
                f"Wb gives a back-EMF of only {emf_top_v:.3g} V peak phase even at "
                f"{fmt_num(TELEMETRY_SPEED_MAX_RPM)} r/min (the most a profile may run), "
                f"{100 * emf_top_v / reach_v:.2g} % of the DC link's {link}, where a motor for "
                f"this link uses tens of % at its rated speed: psi_f_wb is in Wb (25 mWb is "
                f"0.025); {PSI_F_HINT}",
            )
        )
    for key in ("l_d_h", "l_q_h"):
        l_h = getattr(motor, key)
        slew_s = l_h * motor.i_max_a / reach_v
        what = (
            f"H: the DC link's {link} takes {slew_s:.3g} s to drive i_max_a "
            f"{fmt_num(motor.i_max_a)} A into it"
        )
        if slew_s > SLEW_MAX_S:
            out.append(
                _warn(
                    motor_src,
                    key,
                    l_h,
                    f"{what}, where motors take a few ms: {key} is in H, per phase (1.6 mH is "
                    f"0.0016)",
                )
            )
        elif ts_s is not None and slew_s < SLEW_MIN_PERIODS * ts_s:
            out.append(
                _warn(
                    motor_src,
                    key,
                    l_h,
                    f"{what}, under a tenth of a control period (control.ts_s {fmt_num(ts_s)} "
                    f"s): one period at full voltage moves the current by "
                    f"{ts_s / slew_s:.3g} x i_max_a; {key} is in H (1.6 mH is 0.0016)",
                )
            )
    drop_v = motor.r_s_ohm * motor.i_max_a
    if drop_v > R_DROP_MAX * reach_v:
        out.append(
            _warn(
                motor_src,
                "r_s_ohm",
                motor.r_s_ohm,
                f"ohm needs {drop_v:.4g} V to carry i_max_a {fmt_num(motor.i_max_a)} A even at "
                f"standstill, {drop_v / reach_v:.3g} x the DC link's {link}: the current limit can "
                f"never be reached; r_s_ohm is in ohm, per phase (350 mohm is 0.35)",
            )
        )
    return out


def ramp_warnings(src: Source, motor: Motor) -> list[str]:
    """Warnings for run segments whose speed ramp needs more torque to accelerate the motor's
    inertia (plus the segment's load) than its torque_max_nm: the speed lags the ramp."""
    out: list[str] = []
    segments = src.data.get("segments") if isinstance(src.data.get("segments"), list) else []
    speed = 0.0
    for i, seg in enumerate(segments):
        if not isinstance(seg, dict):
            continue
        v, ramp = num(seg, "speed_rpm"), num(seg, "ramp_rpm_s", 0.0)
        load = num(seg, "load_nm", 0.0)
        if v is None or ramp is None or load is None:
            continue
        if seg.get("kind", "run") == "run" and ramp > 0 and v != speed:
            accel_nm = motor.j_kgm2 * ramp * math.pi / 30.0
            need_nm = accel_nm + (abs(load) if abs(v) > abs(speed) else 0.0)
            if need_nm > motor.torque_max_nm:
                out.append(
                    f"{src.path}:{src.line(('segments', i, 'ramp_rpm_s'))}: "
                    f"segments[{i}].ramp_rpm_s = {fmt_num(ramp)} needs {accel_nm:.4g} N m to "
                    f"accelerate j_kgm2 {fmt_num(motor.j_kgm2)} kg m^2 (J x "
                    f"{ramp * math.pi / 30.0:.4g} rad/s^2"
                    f"{f', plus load_nm {fmt_num(load)}' if need_nm > accel_nm else ''}), "
                    f"beyond the motor's torque_max_nm {fmt_num(motor.torque_max_nm)} N m "
                    f"({motor.path}): the speed will lag the ramp; lower ramp_rpm_s, or check "
                    f"j_kgm2 (kg m^2: 0.35 kg cm^2 is 3.5e-05)"
                )
        speed = v
    return out


def load_step_warnings(src: Source, motor: Motor, kp_a_per_rad_s: float | None) -> list[str]:
    """Warnings for load steps between run segments that swing the speed beyond the motor's
    speed_trip_rpm (the firmware faults over_speed there): the swing LOAD_STEP_SWING dT / (J bw),
    with bw the speed loop's crossover (kp k_t / J for the profile's kp, else the designed one's)."""
    out: list[str] = []
    segments = src.data.get("segments") if isinstance(src.data.get("segments"), list) else []
    if motor.j_kgm2 <= 0:
        return out
    bw = DEFAULT_SPEED_BW_RAD_S
    if kp_a_per_rad_s is not None:
        bw = kp_a_per_rad_s * motor.k_t_nm_per_a / motor.j_kgm2
    speed = load = 0.0
    for i, seg in enumerate(segments):
        if not isinstance(seg, dict) or seg.get("kind", "run") != "run":
            continue
        v, new = num(seg, "speed_rpm"), num(seg, "load_nm", 0.0)
        if v is None or new is None:
            continue
        # a load that rises brakes the rotor (positive speed) and one that falls speeds it up
        swing_rpm = -LOAD_STEP_SWING * (new - load) / (motor.j_kgm2 * bw) * 30.0 / math.pi
        peak = speed + swing_rpm
        if new != load and abs(speed + LOAD_STEP_MARGIN * swing_rpm) > motor.speed_trip_rpm:
            out.append(
                f"{src.path}:{src.line(('segments', i, 'load_nm'))}: segments[{i}].load_nm = "
                f"{fmt_num(new)} steps the load from {fmt_num(load)} N m at {fmt_num(speed)} r/min: "
                f"with j_kgm2 {fmt_num(motor.j_kgm2)} kg m^2 and the speed loop's {bw:.0f} rad/s "
                f"the speed swings by about {abs(swing_rpm):.0f} r/min (10 % more at most), to "
                f"{peak:.0f} r/min, at or beyond the motor's speed_trip_rpm "
                f"{fmt_num(motor.speed_trip_rpm)} ({motor.path}): the run may fault over_speed; "
                f"step the load in two segments, or less"
            )
        speed, load = v, new
    return out
