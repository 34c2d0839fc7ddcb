"""From a motor file and a rig file to the sim board's settings (firmware/sim/board.c keys)."""
from __future__ import annotations


def _eff(rig, name: str):
    effects = getattr(rig, "effects", None) or {}
    e = effects.get(name)
    if e is None or not getattr(e, "enabled", True):
        return None
    return e


def emulator_settings(motor, rig, seed: int = 1, baud: int = 921600,
                      truth_hz: float = 100.0, ts_s: float = 50e-6) -> dict[str, float]:
    """The plant is the motor file's motor with the rig's effects; the firmware learns its own
    (nominal) view of the motor over the link."""
    s: dict[str, float] = {
        "r_s_ohm": motor.r_s_ohm, "l_d_h": motor.l_d_h, "l_q_h": motor.l_q_h,
        "psi_f_wb": motor.psi_f_wb, "pole_pairs": motor.pole_pairs, "j_kgm2": motor.j_kgm2,
        "b_visc_nms": getattr(motor, "b_visc_nms", 0.0) or 0.0,
        "t_coulomb_nm": getattr(motor, "t_coulomb_nm", 0.0) or 0.0,
        "v_dc_v": getattr(rig, "v_dc_v", None) or motor.v_dc_v,
        "seed": seed, "baud": baud, "ts_s": ts_s,
        "truth_div": max(1, round(1.0 / (truth_hz * ts_s))) if truth_hz else 0,
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
    s["enc_offset_rad"] = getattr(enc, "offset_rad", 0.0) if enc else 0.0
    fr = _eff(rig, "friction")
    if fr is not None:
        # the rig's friction adds to the motor file's nominal friction (docs/profiles.md)
        s["b_visc_nms"] += fr.b_visc_nms
        s["t_coulomb_nm"] += fr.t_coulomb_nm
    return s
