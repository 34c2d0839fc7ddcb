"""The torque-balance view (docs/gap.md, "Which"): the effects that the one-step current residual
barely sees but the mechanics do: friction, cogging, and current-sensor offsets (an offset makes
the real current differ from the measured one by a vector fixed in the stationary frame, so the
torque computed from the measured current has a ripple at the electrical frequency that the
speed does not follow).

Over windows [t_s, t_s+W] of a run, J (omega(t_s+W) - omega(t_s)) = integral of (T_e - T_load -
friction - cogging). The speed is the zero-phase Savitzky-Golay derivative (quadratic, window N) of
the unwrapped recorded angle: the recorded speed of a drive is usually an observer's or a filter's
output that lags during the ramps, and a lagging speed puts a torque error of J times the
acceleration change at every ramp end, correlated with the sign of the speed (a spurious Coulomb
term). The torques are smoothed by the same filter, so both sides see the same time response. The
windows' balance is regressed on nuisance terms (offset, torque-constant error) and the effects'
regressors, each filtered and averaged as the torques are.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solveh_banded
from scipy.signal import savgol_filter

from pmsm_hil.gap.model import MotorModel, abc_to_ab, rot
from pmsm_hil.gap.record import ControlRecord

MECH_Z = 5.0  # Wald statistic (as a z) for a mechanical effect or an offset
COG_Z = 7.0  # geometric mean of the z on the two window lengths, for the best of 28 orders
# model-form uncertainty added to the statistical error of the magnitudes, relative to them (the
# smoothing and window discretisation of the balance; calibrated on single-effect records)
MODEL_FORM_REL = 0.03
OMEGA_COULOMB_RAD_S = 1.0  # width of the smooth sign of the speed in the Coulomb regressor
# (Savitzky-Golay window in samples, balance window in s): long windows for the slowly varying
# friction terms, short ones for the ripple terms (offsets at the electrical frequency, cogging)
SLOW = (41, 5e-3)
FAST = (21, 1e-3)
MID = (41, 2.5e-3)


@dataclass
class Windows:
    y: np.ndarray  # torque-balance error per window (N m)
    cols: dict[str, np.ndarray]  # regressors per window
    run: np.ndarray  # the run each window belongs to


def _smooth_rows(x: np.ndarray, sg_n: int) -> np.ndarray:
    return savgol_filter(x, sg_n, 2, axis=0)


def balance_windows(
    rec: ControlRecord,
    m: MotorModel,
    sg_n: int,
    w_s: float,
    orders: Sequence[int] = (),
    recorded_speed: bool = False,
) -> Windows | None:
    """Windows of the torque balance and the regressors (see the module doc); ``orders``: cogging
    periods per mechanical revolution whose sin/cos regressors are wanted (``sin{N}``, ``cos{N}``).
    recorded_speed: use the record's own speed column instead (biased where it lags; kept to show
    the bias)."""
    ts = rec.ts_s
    w = max(round(w_s / ts), 4)
    h = sg_n // 2
    i_dq = rot(abc_to_ab(rec.i_abc), -rec.theta_e_rad)
    id_, iq = i_dq[:, 0], i_dq[:, 1]
    p = m.pole_pairs
    dl = m.l_d_h - m.l_q_h
    te = 1.5 * p * (m.psi_f_wb * iq + dl * id_ * iq)
    # d T_e / d i_dq at the measured current, and the offset regressors: an offset o (alpha-beta)
    # adds R(-theta) o to the measured i_dq, so T_e(measured) - T_e(true) = grad . R(-theta) o
    g_d, g_q = 1.5 * p * dl * iq, 1.5 * p * (m.psi_f_wb + dl * id_)
    c, s = np.cos(rec.theta_e_rad), np.sin(rec.theta_e_rad)
    off_a = g_d * c - g_q * s
    off_b = g_d * s + g_q * c
    # 5th and 7th harmonics of the EMF give a torque ripple at 6 theta_e proportional to the current
    c6, s6 = np.cos(6 * rec.theta_e_rad), np.sin(6 * rec.theta_e_rad)
    harm = [id_ * c6, id_ * s6, iq * c6, iq * s6]
    ys, cols_out, run_id = [], [], []
    names = ["one", "iq", "fric_c", "fric_v", "off_a", "off_b", *HARM]
    for n_per in orders:
        names += [f"sin{n_per}", f"cos{n_per}"]
    for a, b in rec.runs:
        if b - a < sg_n + 2 * w:
            continue
        th_m = np.unwrap(rec.theta_e_rad[a:b]) / p
        wm = savgol_filter(th_m, sg_n, 2, deriv=1, delta=ts)
        if recorded_speed:
            wm = rec.omega_e_rad_s[a:b] / p
        if rec.load_nm is None:
            raise ValueError(f"{rec.source}: the torque balance needs the load torque (load_nm)")
        load = rec.load_nm[a:b]
        y0 = te[a:b] - load - m.b_visc_nms * wm - m.t_coulomb_nm * np.sign(wm)
        sig = [
            y0,
            np.ones(b - a),
            iq[a:b],
            np.tanh(wm / OMEGA_COULOMB_RAD_S),
            wm,
            off_a[a:b],
            off_b[a:b],
        ] + [h[a:b] for h in harm]
        for n_per in orders:
            sig += [np.sin(n_per * th_m), np.cos(n_per * th_m)]
        sm = _smooth_rows(np.stack(sig, 1), sg_n)
        starts = np.arange(h, b - a - h - w, w)
        if len(starts) == 0:
            continue
        # trapezoidal mean over [t_s, t_s+W]
        cs = np.cumsum(sm, axis=0)
        tot = cs[starts + w] - cs[starts] + 0.5 * (sm[starts] - sm[starts + w])
        mean = tot / w
        acc = (wm[starts + w] - wm[starts]) / (w * ts)
        ys.append(mean[:, 0] - m.j_kgm2 * acc)
        cols_out.append(mean[:, 1:])
        run_id.append(np.full(len(starts), a))
    if not ys:
        return None
    y = np.concatenate(ys)
    x = np.concatenate(cols_out)
    return Windows(y, {n: x[:, j] for j, n in enumerate(names)}, np.concatenate(run_id))


def ols(wins: Windows, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """Feasible GLS of the balance on the named regressors: coefficients and their covariance.

    A window's error is J (n(t_s+W) - n(t_s))/W for the speed estimate's error n (white, from the
    angle's quantisation) plus a model error u: neighbouring windows share an edge, so the errors
    are MA(1) with lag-1 correlation rho = -a/(2a + u) (near -0.5 when the speed noise dominates,
    where ordinary least squares would overstate the error of slowly varying terms many times).
    a and u are estimated from the ordinary least-squares residual, then the covariance is scaled
    by the GLS residual's own variance."""
    X = np.stack([wins.cols[n] for n in names], 1)
    y = wins.y
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    res = y - X @ beta
    same = wins.run[1:] == wins.run[:-1]
    var = float(res @ res) / len(res)
    rho = float(np.sum(res[1:] * res[:-1] * same)) / max(var * np.count_nonzero(same), 1e-300)
    a = max(-rho, 0.0) * var
    u = max(var - 2.0 * a, 0.02 * var)
    ab = np.zeros((2, len(y)))
    ab[1] = 2.0 * a + u
    ab[0, 1:] = np.where(same, -a, 0.0)
    try:
        si_x = solveh_banded(ab, X)
        si_y = solveh_banded(ab, y)
    except np.linalg.LinAlgError:
        s2 = float(res @ res) / max(len(res) - X.shape[1], 1)
        return beta, s2 * np.linalg.pinv(X.T @ X)
    H = np.linalg.pinv(X.T @ si_x)
    beta = H @ (X.T @ si_y)
    r = y - X @ beta
    scale = float(r @ solveh_banded(ab, r)) / max(len(r) - X.shape[1], 1)
    return beta, H * scale


def wald_z(beta: np.ndarray, cov: np.ndarray) -> float:
    """A joint test of several coefficients, as a z: sqrt(beta' cov^-1 beta)."""
    return float(np.sqrt(max(beta @ np.linalg.pinv(cov) @ beta, 0.0)))


NUIS = ["one", "iq"]
FRIC = ["fric_c", "fric_v"]
OFFS = ["off_a", "off_b"]
HARM = ["h_dc", "h_ds", "h_qc", "h_qs"]


def _entry(name, quantity, why):
    return {
        "name": name,
        "selected": False,
        "magnitude": None,
        "quantity": quantity,
        "interval": None,
        "closure": None,
        "evidence": why,
    }


def torque_balance_effects(rec: ControlRecord, m: MotorModel) -> list[dict]:
    """friction, cogging and sensor_offset entries from the torque balance."""
    why = "needs the load torque and the motor's inertia (load_nm, j_kgm2)"
    none = [
        _entry("friction", "t_coulomb_nm", why),
        _entry("cogging", "amplitude_nm", why),
        _entry("sensor_offset", "offset_norm_a", why),
    ]
    if rec.load_nm is None or not m.j_kgm2 or np.any(np.isnan(rec.load_nm)):
        return none
    p = m.pole_pairs
    # cogging: lcm(slots, 2p) periods per revolution, a multiple of p; orders p and 2p are left
    # out (an offset and a relative gain error of the current sensors ripple there)
    orders = list(range(3 * p, 30 * p + 1, p))
    fast = balance_windows(rec, m, *FAST, orders=orders)
    if fast is None or len(fast.y) < 50:
        return none
    mid = balance_windows(rec, m, *MID, orders=orders)
    if mid is None or len(mid.y) < 50:
        mid = fast
    # two window lengths: the short one keeps the high cogging frequencies, the longer one has a
    # quieter speed at the low ones. A cogging shows on both, the balance's other departures (the
    # speed loop's updates, the smoothing at the ramps' corners) on one: the order is scored by the
    # geometric mean of its two z, the magnitude taken from the window with the larger z
    best = None
    for n_per in orders:
        names = [f"sin{n_per}", f"cos{n_per}"]
        # at 6p periods per turn a cogging torque is told from the EMF harmonics' torque ripple
        # by not following the current
        nuis = NUIS + FRIC + OFFS + (HARM if n_per == 6 * p else [])
        fits = []
        for wins in (fast, mid):
            bb, cc = ols(wins, nuis + names)
            fits.append((wald_z(bb[-2:], cc[-2:, -2:]), bb, cc))
        z = float(np.sqrt(fits[0][0] * fits[1][0]))
        if best is None or z > best[0]:
            _, bb, cc = max(fits, key=lambda f: f[0])
            amp = float(np.hypot(*bb[-2:]))
            g = bb[-2:] / max(amp, 1e-12)
            se = float(np.hypot(np.sqrt(max(g @ cc[-2:, -2:] @ g, 0.0)), MODEL_FORM_REL * amp))
            # the balance error is minus the cogging torque A sin(N theta_m + phase)
            phase = float(np.arctan2(-bb[-1], -bb[-2]))
            best = (z, n_per, amp, se, phase, bb, cc)
    assert best is not None  # orders holds 28 cogging orders, so the loop always sets best
    z, n_per, amp, se, phase, bb, cc = best
    cog_cols = [f"sin{n_per}", f"cos{n_per}"]  # the likeliest cogging, a nuisance of the others
    cog = {
        "name": "cogging",
        "selected": bool(z > COG_Z),
        "magnitude": amp,
        "quantity": "amplitude_nm",
        "interval": [max(amp - 1.96 * se, 0.0), amp + 1.96 * se],
        "closure": None,
        "parameters": {"amplitude_nm": amp, "periods_per_rev": n_per, "phase_rad": phase},
        "evidence": f"torque balance: {n_per} periods per revolution, {amp:.3g} N m, z = {z:.1f} "
        f"(geometric mean over 1 and 2.5 ms windows; threshold {COG_Z:g})",
    }
    # sensor offsets: the ripple at the electrical frequency
    b, cov = ols(fast, NUIS + FRIC + cog_cols + OFFS)
    o, co = b[-2:], cov[-2:, -2:]
    z_o = wald_z(o, co)
    norm = float(np.hypot(*o))
    gdir = o / max(norm, 1e-12)
    se_n = float(np.hypot(np.sqrt(max(gdir @ co @ gdir, 0.0)), MODEL_FORM_REL * norm))
    i_a = float(o[0])
    i_b = float((np.sqrt(3.0) * o[1] - o[0]) / 2.0)
    offs = {
        "name": "sensor_offset",
        "selected": bool(z_o > MECH_Z),
        "magnitude": norm,
        "quantity": "offset_norm_a",
        "interval": [max(norm - 1.96 * se_n, 0.0), norm + 1.96 * se_n],
        "closure": None,
        "parameters": {"i_a_a": i_a, "i_b_a": i_b, "i_c_a": 0.0},
        "evidence": f"torque balance: ripple at the electrical frequency of a current offset "
        f"{norm:.3g} A, z = {z_o:.1f} (threshold {MECH_Z:g})",
    }
    # friction: Coulomb and viscous terms beyond the motor file's nominal friction
    slow = balance_windows(rec, m, *SLOW, orders=[n_per])
    if slow is None or len(slow.y) < 20:
        return [_entry("friction", "t_coulomb_nm", "record too short"), cog, offs]
    b, cov = ols(slow, NUIS + OFFS + cog_cols + FRIC)
    tc, bv = float(b[-2]), float(b[-1])
    se_stat = float(np.sqrt(cov[-2, -2]))
    z_tc = tc / se_stat if se_stat > 0 else 0.0
    se_tc = float(np.hypot(se_stat, MODEL_FORM_REL * tc))
    fric = {
        "name": "friction",
        "selected": bool(z_tc > MECH_Z),
        "magnitude": tc,
        "quantity": "t_coulomb_nm",
        "interval": [tc - 1.96 * se_tc, tc + 1.96 * se_tc],
        "closure": None,
        "parameters": {"t_coulomb_nm": tc, "b_visc_nms": bv},
        "evidence": f"torque balance over {SLOW[1] * 1e3:g} ms windows: Coulomb term "
        f"{tc:.3g} N m, t = {z_tc:.1f} (threshold {MECH_Z:g})",
    }
    return [fric, cog, offs]
