"""From a motor file and a rig file to the sim board's settings (firmware/sim/board.c keys)."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pmsm_hil.profiles import Motor, Rig


def _eff(rig, name: str):
    effects = getattr(rig, "effects", None) or {}
    e = effects.get(name)
    if e is None or not getattr(e, "enabled", True):
        return None
    return e


def emulator_settings(
    motor: Motor,
    rig: Rig,
    seed: int = 1,
    baud: int = 921600,
    truth_hz: float = 100.0,
    ts_s: float = 50e-6,
) -> dict[str, float]:
    """The plant is the motor file's motor with the rig's effects; the firmware learns its own
    (nominal) view of the motor over the link. A commissioned motor file (docs/commissioning.md)
    holds what the firmware measured; the plant stays the machine of its nominal values."""
    from pmsm_hil.profiles.motor import nominal_machine

    motor = nominal_machine(motor)
    dev = _eff(rig, "motor_deviation")
    pole_pairs = rig.plant_pole_pairs(motor.pole_pairs)
    s: dict[str, float] = {
        "r_s_ohm": motor.r_s_ohm,
        "l_d_h": motor.l_d_h,
        "l_q_h": motor.l_q_h,
        "psi_f_wb": motor.psi_f_wb,
        "pole_pairs": pole_pairs,
        "j_kgm2": motor.j_kgm2,
        "b_visc_nms": getattr(motor, "b_visc_nms", 0.0) or 0.0,
        "t_coulomb_nm": getattr(motor, "t_coulomb_nm", 0.0) or 0.0,
        "v_dc_v": getattr(rig, "v_dc_v", None) or motor.v_dc_v,
        "seed": seed,
        "baud": baud,
        "ts_s": ts_s,
        "truth_hz": truth_hz,  # the sim board counts it in the firmware's periods
    }
    dt = _eff(rig, "dead_time")
    s["dead_time_s"] = dt.dead_time_s if dt else 0.0
    s["v_drop_v"] = dt.v_drop_v if dt else 0.0
    s["i_dt_a"] = dt.i_dt_a if dt else 0.5
    noise = _eff(rig, "adc_noise")
    s["i_noise_a"] = noise.i_noise_a if noise else 0.0
    quant = _eff(rig, "adc_quantisation")
    s["adc_lsb_a"] = quant.adc_lsb_a if quant else 0.0
    enc = _eff(rig, "encoder")
    s["enc_counts"] = 4 * int(getattr(enc, "lines", 2500)) if enc else 10000
    # the rig gives the offset as an electrical angle; the plant's encoder adds it to theta_m
    s["enc_offset_m_rad"] = getattr(enc, "offset_e_rad", 0.0) / pole_pairs if enc else 0.0
    if dev is not None:  # the plant's motor departs from the file (a flux map: effect_settings)
        s["r_s_ohm"] *= dev.r_s_factor
        s["l_d_h"] *= dev.l_d_factor
        s["l_q_h"] *= dev.l_q_factor
        s["psi_f_wb"] *= dev.psi_f_factor
    fr = _eff(rig, "friction")
    if fr is not None:
        # the rig's friction adds to the motor file's nominal friction (docs/profiles.md)
        s["b_visc_nms"] += fr.b_visc_nms
        s["t_coulomb_nm"] += fr.t_coulomb_nm
    s.update(effect_settings(motor, rig))
    return s


# RK4 sub-steps per period when the plant has a flux map: one, as the plant integrates a map in the
# flux linkage (docs/plant.md "Integration"; four were needed while it integrated the currents)
MAP_SUBSTEPS = 1


def _motor_map(motor: Motor):
    """The motor's own magnetics, which the rig departs from (not a linear model): the nominal
    machine's map of a commissioned file (`commissioning.nominal.flux_map`, None: linear), else
    the file's `flux_map`."""
    from pmsm_hil.profiles.motor import NominalMachine

    if isinstance(motor, NominalMachine) and "flux_map" in motor._nominal:
        rel = motor._nominal["flux_map"]
        if not rel:
            return None
        from pmsm_hil.profiles.fluxmap import load_flux_map

        base = os.path.dirname(motor.path or ".")
        return load_flux_map(rel if os.path.isabs(rel) else os.path.join(base, rel))
    return motor.load_flux_map() if getattr(motor, "flux_map", None) else None


def effect_settings(motor: Motor, rig: Rig) -> dict:
    """The sim board's keys for the effects of issue 5 (docs/rigs.md). Every key is set, to its
    'off' value when the effect is disabled, so that a disabled effect leaves the ideal plant."""
    s: dict = {"effects_mask": int(getattr(rig, "effects_mask", 0) or 0)}
    wiring = getattr(rig, "wiring", None)
    s["wiring_swap_bc"] = 1 if wiring is not None and wiring.phases == "acb" else 0
    s["wiring_open"] = 1 if wiring is not None and not wiring.motor_connected else 0
    sat = _eff(rig, "saturation")
    fm = rig.flux_map() if sat is not None else _motor_map(motor)
    if sat is not None and fm is not None:  # another motor's map: its saturation, scaled
        from pmsm_hil.profiles.fluxmap import for_motor

        fm, _ = for_motor(fm, motor.psi_f_wb, motor.l_d_h, motor.l_q_h)
    dev = _eff(rig, "motor_deviation")
    if fm is not None and dev is not None:  # the plant's map departs from the motor's likewise
        psi_m, l_d_m, l_q_m = fm.small_current()
        fm, _ = fm.scaled_to(
            psi_m * dev.psi_f_factor, l_d_m * dev.l_d_factor, l_q_m * dev.l_q_factor
        )
    if fm is not None:
        s.update(fm.settings())
        # RK4 in the currents missed a map's voltage equation by 0.2-0.6 V on q at one sub-step
        # (an FCS period moves the current across several of the map's cells); in the flux
        # linkage one step meets it to the noise of the check (docs/plant.md "Integration")
        s["substeps"] = MAP_SUBSTEPS
    else:
        s.update({"sat_nd": 0, "sat_nq": 0})
        s["substeps"] = 1
    th = _eff(rig, "thermal")
    s["thermal_on"] = 1 if th is not None else 0
    if th is not None:
        s.update(
            {
                "temp_ambient_c": th.temp_ambient_c,
                "temp_ref_c": th.temp_ref_c,
                "temp_winding0_c": th.temp_winding_c,
                "temp_magnet0_c": th.temp_magnet_c,
                "alpha_r_per_k": th.alpha_r_per_k,
                "alpha_psi_per_k": th.alpha_psi_per_k,
                "c_winding_j_k": th.c_winding_j_k,
                "c_magnet_j_k": th.c_magnet_j_k,
                "r_wa_k_w": th.r_wa_k_w,
                "r_wm_k_w": th.r_wm_k_w,
                "r_ma_k_w": th.r_ma_k_w,
                "r_fe_heat_ohm": th.r_fe_heat_ohm,
            }
        )
    fh = _eff(rig, "flux_harmonics")
    # the n-th flux harmonic gives the n-th back-EMF harmonic n times larger (relative to psi_f)
    s["psi5_rel"] = fh.emf5_rel / 5.0 if fh is not None else 0.0
    s["psi7_rel"] = fh.emf7_rel / 7.0 if fh is not None else 0.0
    cg = _eff(rig, "cogging")
    s["cog_nm"] = cg.amplitude_nm if cg is not None else 0.0
    if cg is not None:
        # periods_per_rev is a multiple of pole_pairs (checked when the profile is loaded:
        # pmsm_hil.profiles.rig.plant_problems)
        s["cog_order_e"] = cg.periods_per_rev // rig.plant_pole_pairs(motor.pole_pairs)
        s["cog_phase_rad"] = cg.phase_rad
    so = _eff(rig, "sensor_offset")
    for ch in "abc":
        s[f"i_{ch}_offset_a"] = getattr(so, f"i_{ch}_a") if so is not None else 0.0
    sg = _eff(rig, "sensor_gain")
    for ch in "abc":
        s[f"i_{ch}_gain"] = getattr(sg, f"i_{ch}_gain") if sg is not None else 1.0
    dl = _eff(rig, "delay")
    s["sample_delay_s"] = dl.sample_delay_s if dl is not None else 0.0
    s["pwm_delay_periods"] = dl.pwm_delay_periods if dl is not None else 0
    dc = _eff(rig, "dc_link")
    s["dc_on"] = 1 if dc is not None else 0
    if dc is not None:
        s.update(
            {
                "dc_r_src_ohm": dc.r_source_ohm,
                "dc_c_f": dc.c_dc_f,
                "dc_rectifier": 1 if dc.rectifier else 0,
                "dc_grid_hz": dc.grid_hz,
            }
        )
    fe = _eff(rig, "iron_loss")
    s["r_fe_ohm"] = fe.r_fe_ohm if fe is not None else 0.0
    return s
