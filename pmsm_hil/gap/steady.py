"""Steady-state dq data (e.g. a public data set at a few Hz): the steady voltage equations
u_d = R i_d - w Lq i_q, u_q = R i_q + w (Ld i_d + psi_f) against the motor file (docs/gap.md)."""

from __future__ import annotations

import numpy as np

from pmsm_hil.gap.effects import ALL_NAMES
from pmsm_hil.gap.model import MotorModel
from pmsm_hil.gap.record import SteadyRecord


def diagnose_steady(rec: SteadyRecord, m: MotorModel) -> dict:
    idd, iq = rec.i_dq[:, 0], rec.i_dq[:, 1]
    w = rec.omega_e_rad_s
    ud, uq = rec.u_dq[:, 0], rec.u_dq[:, 1]
    rd = ud - (m.r_s_ohm * idd - w * m.l_q_h * iq)
    rq = uq - (m.r_s_ohm * iq + w * (m.l_d_h * idd + m.psi_f_wb))
    # best constant parameters: unknowns R, Ld, Lq, psi_f (linear)
    z = np.zeros_like(w)
    A = np.vstack([np.stack([idd, z, -w * iq, z], 1), np.stack([iq, w * idd, z, w], 1)])
    y = np.concatenate([ud, uq])
    x, *_ = np.linalg.lstsq(A, y, rcond=None)
    res = y - A @ x
    dof = max(len(y) - 4, 1)
    cov = (res @ res / dof) * np.linalg.pinv(A.T @ A)
    se = np.sqrt(np.maximum(np.diag(cov), 0))
    base = float(np.mean(np.concatenate([rd, rq]) ** 2))
    par = float(np.mean(res**2))
    closure = (base - par) / base if base > 0 else 0.0
    effects: list[dict[str, object]] = []
    out: dict[str, object] = {
        "source": rec.source,
        "samples": len(w),
        "kind": "steady-state dq",
        "base_gap": {"mse_v2": base, "rms_v": float(np.sqrt(base))},
        "parametric_gap": {
            "r_s_ohm": float(x[0]),
            "l_d_h": float(x[1]),
            "l_q_h": float(x[2]),
            "psi_f_wb": float(x[3]),
            "se": [float(s) for s in se],
            "mse_after_v2": par,
            "closure": closure,
        },
        "selected": [],
        "effects": effects,
    }
    temp = rec.temp_winding_c
    if temp is not None and np.ptp(temp) > 5:
        # R against winding temperature from the d-axis equation at low speed
        k = np.abs(idd) > 0.5
        if k.sum() > 5:
            r_pt = (ud[k] + w[k] * x[2] * iq[k]) / idd[k]
            slope, icpt = np.polyfit(temp[k], r_pt, 1)
            out["thermal"] = {
                "r_s_ohm_per_k": float(slope),
                "alpha_r_per_k": float(slope / max(icpt + slope * 25, 1e-9)),
            }
    for n in ALL_NAMES:
        effects.append(
            {
                "name": n,
                "selected": False,
                "magnitude": None,
                "interval": None,
                "closure": None,
                "evidence": "steady-state dq data: only the parametric gap is assessed",
            }
        )
    out["verdict"] = (
        "parametric gap (steady-state data; effects need control-rate data)"
        if closure > 0.5
        else "no structural gap found (steady-state data)"
    )
    return out
