"""From a profile's motor to the sensorless estimator's configuration (docs/sensorless.md): the
polarity test's pulse and expected signature, the hybrid's band, the supervision, and the table of
inverse incremental inductances from the motor's flux map (one gamma_node frame per node)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from pmsm_hil.profiles.magnetics import gamma_table, polarity_signature

if TYPE_CHECKING:
    from pmsm_hil.profiles.motor import Motor

# Supervision (docs/sensorless.md): a difference of more than LOCK_DISAGREE_RAD between the PLL and
# the MRAS for LOCK_DISAGREE_S, or the PLL's confidence (cos 2 d) below LOCK_CONF_MIN for
# LOCK_LOST_S, is a loss of lock.
LOCK_DISAGREE_RAD = 0.3
LOCK_DISAGREE_S = 0.02
LOCK_CONF_MIN = 0.5
LOCK_LOST_S = 0.05
# The polarity test resolves when the measured asymmetry is at least this fraction of the motor's
# own signature (and never below ASYM_MIN_FLOOR: ADC noise gives about 0.001).
ASYM_MIN_FRACTION = 0.3
ASYM_MIN_FLOOR = 0.02
# The ripple PLL's excitation by default: a tenth of the current limit (1.5 A on paper A's motor,
# about 40 % of the d-current step of one active vector in one period; docs/sensorless.md).
EXCITE_SHARE = 0.1
RIPPLE_A = 4.0  # the MPCC's current ripple beyond the references that the table must cover


def polarity_pulse_a(motor: Motor) -> float:
    return motor.polarity_pulse_a or 0.5 * motor.i_max_a


def ripple_pll_excite_a(motor: Motor) -> float:
    """The ripple PLL's d-axis excitation, alternating every control period (docs/sensorless.md)."""
    if motor.ripple_pll_excite_a is not None:
        return float(motor.ripple_pll_excite_a)
    return EXCITE_SHARE * motor.i_max_a


def estimator_frames(motor: Motor) -> tuple[dict, list[dict]]:
    """(config_sensorless fields, gamma_node frames) for `motor`."""
    fm = motor.load_flux_map()
    i_pulse = polarity_pulse_a(motor)
    asym = polarity_signature(fm, i_pulse)
    cfg = dict(
        pol_i_pulse_a=i_pulse,
        pol_asym_expected=asym,
        pol_asym_min=max(ASYM_MIN_FLOOR, ASYM_MIN_FRACTION * abs(asym)),
        hyb_pll_on_rpm=motor.hybrid_pll_on_rpm,
        hyb_mras_on_rpm=motor.hybrid_mras_on_rpm,
        hyb_blend_s=motor.hybrid_blend_s,
        lock_disagree_rad=LOCK_DISAGREE_RAD,
        lock_disagree_s=LOCK_DISAGREE_S,
        lock_conf_min=LOCK_CONF_MIN,
        lock_lost_s=LOCK_LOST_S,
        gam_nd=0,
        gam_nq=0,
        gam_id0_a=0.0,
        gam_iq0_a=0.0,
        gam_did_a=1.0,
        gam_diq_a=1.0,
        if_i_a=float(motor.if_start_current_a or 0.0),
        if_accel_rpm_s=float(motor.if_start_accel_rpm_s),
        if_handover_rpm=float(motor.if_handover_rpm),
        pll_excite_a=ripple_pll_excite_a(motor),
    )
    if fm is None:
        return cfg, []
    i_d_min, _ = motor.mtpa_currents(motor.i_max_a)
    t = gamma_table(fm, i_d_min, motor.i_max_a, RIPPLE_A)
    nd, nq = t.shape
    cfg.update(
        gam_nd=nd,
        gam_nq=nq,
        gam_id0_a=float(t.i_d_a[0]),
        gam_iq0_a=float(t.i_q_a[0]),
        gam_did_a=float(t.i_d_a[1] - t.i_d_a[0]),
        gam_diq_a=float(t.i_q_a[1] - t.i_q_a[0]),
    )
    nodes = [
        dict(
            index=k * nd + j,
            g_dd=float(t.g[k, j, 0]),
            g_qq=float(t.g[k, j, 1]),
            g_dq=float(t.g[k, j, 2]),
            g_qd=float(t.g[k, j, 3]),
        )
        for k in range(nq)
        for j in range(nd)
    ]
    return cfg, nodes
