"""From a profile (motor, rig, control, telemetry) to the device's configuration frames, including
the speed-PI design when the profile leaves the gains to the tool (docs/control.md)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from pmsm_hil.profiles.sections import DEFAULT_SPEED_BW_RAD_S
from pmsm_hil.protocol import generated as gen

if TYPE_CHECKING:
    from pmsm_hil.profiles import Motor, Profile, Rig

DEFAULT_OBSERVER_BW_RAD_S = 1000.0  # encoder speed observer (docs/control.md)
CAPTURE_PRE = 256


def design_speed_pi(motor: Motor, bw_rad_s: float = DEFAULT_SPEED_BW_RAD_S) -> tuple[float, float]:
    """PI on mechanical rad/s -> stator current (A): crossover at bw, PI zero at bw/4."""
    kp = motor.j_kgm2 * bw_rad_s / motor.k_t_nm_per_a
    ki = kp * bw_rad_s / 4.0
    return kp, ki


def _div(rate_hz: float, ts_s: float) -> int:
    return 0 if not rate_hz else max(1, round(1.0 / (rate_hz * ts_s)))


def encoder_counts(rig: Rig) -> int:
    """Counts per revolution the firmware is told: the rig's encoder (its `lines_told` when it
    misstates them; the model's default when the effect is off)."""
    enc = rig.effects.encoder
    if not enc.enabled:
        return int(4 * type(enc).model_fields["lines"].default)
    return int(4 * (enc.lines_told or enc.lines))


def device_config(profile: Profile) -> tuple[dict, dict]:
    """(config_motor fields, config_ctrl fields) for `profile`."""
    m, c, tel = profile.motor, profile.control, profile.telemetry
    motor_cfg = dict(
        pole_pairs=m.pole_pairs,
        r_s_ohm=m.r_s_ohm,
        l_d_h=m.l_d_h,
        l_q_h=m.l_q_h,
        psi_f_wb=m.psi_f_wb,
        j_kgm2=m.j_kgm2,
        i_max_a=m.i_max_a,
        speed_max_rpm=m.speed_max_rpm,
        i_trip_a=m.i_trip_a,
        speed_trip_rpm=m.speed_trip_rpm,
        v_dc_min_v=m.v_dc_min_v,
        v_dc_max_v=m.v_dc_max_v,
    )
    kp, ki = c.speed_kp_a_per_rad_s, c.speed_ki_a_per_rad
    if kp is None or ki is None:
        kp_d, ki_d = design_speed_pi(m)
        kp = kp_d if kp is None else kp
        ki = ki_d if ki is None else ki
    # The firmware compensates the inverter with its own nominal values (the motor file's), never
    # with the rig's: the rig is the plant, which the firmware cannot know (docs/rigs.md).
    comp = c.dead_time_comp
    ctrl_cfg = dict(
        ts_s=c.ts_s,
        rho=c.rho,
        speed_kp_a_per_rad_s=kp,
        speed_ki_a_per_rad=ki,
        speed_div=_div(c.speed_loop_hz, c.ts_s),
        current_ref=gen.ENUMS["current_ref"]["mtpa" if c.current_ref == "mtpa" else "id_zero"],
        current_ctrl=gen.ENUMS["current_ctrl"][c.current_ctrl],
        angle_src=gen.ENUMS["angle_src"][c.angle_src],
        heartbeat_timeout_s=c.heartbeat_timeout_s,
        fast_div=_div(tel.fast_hz, c.ts_s),
        params_div=_div(tel.params_hz, c.ts_s),
        status_div=_div(tel.status_hz, c.ts_s),
        enc_counts=encoder_counts(profile.rig),
        enc_offset_e_rad=getattr(m, "enc_offset_e_rad", 0.0) or 0.0,
        speed_obs_bw_rad_s=c.speed_obs_bw_rad_s or DEFAULT_OBSERVER_BW_RAD_S,
        dead_time_s=m.dead_time_s if comp else 0.0,
        v_drop_v=m.v_drop_v if comp else 0.0,
        i_dt_a=m.i_dt_a if comp else 0.0,
        capture_pre=CAPTURE_PRE,
    )
    ctrl_cfg.update(identification_config(profile))
    ctrl_cfg.update(sensorless_config(profile))
    return motor_cfg, ctrl_cfg


DEFAULT_EST_BW_RAD_S = 300.0  # angle estimator tracking bandwidth (docs/sensorless.md)
MRAS_MIN_SPEED_SHARE = (
    0.05  # MRAS: not used below 5 % of the motor's speed_max_rpm (its rated speed)
)


def foc_bandwidth(profile: Profile) -> float:
    """FOC current-loop bandwidth, rad/s: the profile's, or 2 pi / (20 ts_s) (docs/sensorless.md)."""
    c = profile.control
    return c.foc_bw_rad_s or 2.0 * math.pi / (20.0 * c.ts_s)


def estimator_min_speed_rpm(profile: Profile) -> float:
    """The speed below which the angle estimator is not locked (and not used), r/min."""
    est = profile.control.estimator
    if est.min_speed_rpm is not None:
        return est.min_speed_rpm
    return MRAS_MIN_SPEED_SHARE * profile.motor.speed_max_rpm


def sensorless_config(profile: Profile) -> dict:
    """config_ctrl fields of the current controller's options and the angle estimator."""
    c, tel = profile.control, profile.telemetry
    est = c.estimator
    return dict(
        mpcc_candidates=gen.ENUMS["mpcc_candidates"][c.mpcc_candidates],
        foc_bw_rad_s=foc_bandwidth(profile),
        est_bw_rad_s=est.bw_rad_s or DEFAULT_EST_BW_RAD_S,
        est_min_speed_rpm=estimator_min_speed_rpm(profile),
        est_lock_timeout_s=est.lock_timeout_s,
        est_theta0_rad=est.theta0_rad,
        est_div=_div(tel.est_hz, c.ts_s),
    )


def identification_config(profile: Profile) -> dict:
    """config_ctrl fields of the online identification (docs/identification.md)."""
    c = profile.control
    sc = c.predictor_scale
    return dict(
        identify=1 if c.identify else 0,
        predictor=gen.ENUMS["estimator"][c.predictor],
        id_window=max(2, round(c.id_window_s / c.ts_s)),
        pred_scale_l_d=sc.l_d_h,
        pred_scale_l_q=sc.l_q_h,
        pred_scale_psi_f=sc.psi_f_wb,
        pred_scale_r_s=sc.r_s_ohm,
    )


def calibration_config(motor: Motor) -> dict | None:
    """config_calib fields from a commissioned motor file's current-sensor calibration, or None
    when the file has none (the message is then not sent: the firmware uses raw samples)."""
    cal = getattr(motor, "current_sensors", None)
    if cal is None:
        return None
    return dict(
        i_a_offset_a=cal.i_a_offset_a,
        i_b_offset_a=cal.i_b_offset_a,
        i_c_offset_a=cal.i_c_offset_a,
        i_a_gain_err=cal.i_a_gain_err,
        i_b_gain_err=cal.i_b_gain_err,
        i_c_gain_err=cal.i_c_gain_err,
    )
