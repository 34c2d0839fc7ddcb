"""Views for the effects the one-step current residual does not fit (docs/gap.md, "Which"):
dc_link from the measured DC-link voltage, friction and cogging from the torque balance."""

from __future__ import annotations

import numpy as np

from pmsm_hil.gap.model import MotorModel, abc_to_ab, rot

WINDOW_S = 1e-3
DC_RIPPLE_REL = 0.002  # DC-link voltage varying by more than 0.2 % rms: a soft link
MECH_Z = 5.0  # t statistic for a mechanical effect


def _dc_link(rec) -> dict:
    v = rec.v_dc_v
    if rec.voltage_kind == "alphabeta" or np.all(np.isnan(v)):
        return {
            "name": "dc_link",
            "selected": False,
            "magnitude": None,
            "quantity": "v_dc_ripple_rms_v",
            "interval": None,
            "closure": None,
            "evidence": "no DC-link voltage in the data",
        }
    sd = float(np.std(v))
    # 95 % interval of the rms deviation: bootstrap over 20 ms blocks of the squared deviation
    sq = (v - np.mean(v)) ** 2
    nb = max(len(v) // max(round(0.02 / rec.ts_s), 1), 2)
    blocks = np.array([p.mean() for p in np.array_split(sq, nb)])
    rng = np.random.default_rng(0)
    boot = np.sqrt(blocks[rng.integers(0, nb, size=(400, nb))].mean(1))
    ci = [float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5))]
    rel = sd / max(float(np.mean(v)), 1e-9)
    return {
        "name": "dc_link",
        "selected": bool(rel > DC_RIPPLE_REL),
        "magnitude": sd,
        "quantity": "v_dc_ripple_rms_v",
        "interval": ci,
        "closure": None,
        "evidence": f"measured v_dc varies {rel:.2%} rms (threshold {DC_RIPPLE_REL:.1%}); the probe uses the "
        f"measured v_dc, so the current residual does not carry it",
    }


def _mech(rec, m: MotorModel) -> list[dict]:
    none = [
        {
            "name": n,
            "selected": False,
            "magnitude": None,
            "quantity": q,
            "interval": None,
            "closure": None,
            "evidence": why,
        }
        for n, q in (("friction", "t_coulomb_nm"), ("cogging", "amplitude_nm"))
        for why in ["needs the load torque and the motor's inertia (load_nm, j_kgm2)"]
    ]
    if rec.load_nm is None or not m.j_kgm2:
        return none
    w = max(round(WINDOW_S / rec.ts_s), 4)
    idx = []
    for a, b in rec.runs:
        starts = np.arange(a, b - w, w)
        idx.extend(starts.tolist())
    idx = np.array(idx, dtype=np.int64)
    if len(idx) < 50:
        return none
    i_dq = rot(abc_to_ab(rec.i_abc), -rec.theta_e_rad)
    te = (
        1.5
        * m.pole_pairs
        * (m.psi_f_wb * i_dq[:, 1] + (m.l_d_h - m.l_q_h) * i_dq[:, 0] * i_dq[:, 1])
    )
    win = idx[:, None] + np.arange(w)[None, :]
    wm = rec.omega_e_rad_s / m.pole_pairs
    acc = (wm[idx + w] - wm[idx]) / (w * rec.ts_s)
    te_w, tl_w, wm_w = te[win].mean(1), rec.load_nm[win].mean(1), wm[win].mean(1)
    th_m = np.unwrap(rec.theta_e_rad) / m.pole_pairs
    y = te_w - tl_w - m.b_visc_nms * wm_w - m.t_coulomb_nm * np.sign(wm_w) - m.j_kgm2 * acc
    nuis = [np.ones_like(y), i_dq[win, 1].mean(1)]  # offset and torque-constant error
    fr = [np.tanh(wm_w / 1.0), wm_w]

    def tstat(cols, extra):
        X = np.stack(nuis + extra + cols, 1)
        beta, *_ = np.linalg.lstsq(X, y, rcond=None)
        res = y - X @ beta
        s2 = res @ res / max(len(y) - X.shape[1], 1)
        cov = s2 * np.linalg.pinv(X.T @ X)
        nc = len(cols)
        return beta[-nc:], np.sqrt(np.diag(cov)[-nc:])

    b, se = tstat(fr, [])
    fric = {
        "name": "friction",
        "selected": bool(abs(b[0]) / se[0] > MECH_Z and b[0] > 0),
        "magnitude": float(b[0]),
        "quantity": "t_coulomb_nm",
        "interval": [float(b[0] - 1.96 * se[0]), float(b[0] + 1.96 * se[0])],
        "closure": None,
        "parameters": {"t_coulomb_nm": float(b[0]), "b_visc_nms": float(b[1])},
        "evidence": f"torque balance over {WINDOW_S * 1e3:g} ms windows: Coulomb term t = {b[0] / se[0]:.1f}",
    }
    best = None
    for n_per in range(m.pole_pairs, 30 * m.pole_pairs + 1, m.pole_pairs):
        cols = [np.sin(n_per * th_m)[win].mean(1), np.cos(n_per * th_m)[win].mean(1)]
        bb, ss = tstat(cols, fr)
        amp = float(np.hypot(*bb))
        z = amp / float(np.hypot(*ss) / np.sqrt(2))
        if best is None or z > best[0]:
            best = (z, n_per, amp, float(np.hypot(*ss) / np.sqrt(2)))
    z, n_per, amp, sa = best
    # many periods were tried: demand a larger t than for one
    cog = {
        "name": "cogging",
        "selected": bool(z > MECH_Z + 1.5),
        "magnitude": amp,
        "quantity": "amplitude_nm",
        "interval": [max(amp - 1.96 * sa, 0.0), amp + 1.96 * sa],
        "closure": None,
        "parameters": {"amplitude_nm": amp, "periods_per_rev": n_per},
        "evidence": f"torque balance: {n_per} periods per revolution, t = {z:.1f}",
    }
    return [fric, cog]


def view_effects(rec, m: MotorModel) -> list[dict]:
    return [_dc_link(rec), *_mech(rec, m)]
