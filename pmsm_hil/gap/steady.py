"""Steady-state dq data (e.g. a public data set at a few Hz): the steady voltage equations
u_d = R i_d - w Lq i_q, u_q = R i_q + w (Ld i_d + psi_f) against the motor file (docs/gap.md)."""

from __future__ import annotations

import numpy as np

from pmsm_hil.gap.model import MotorModel
from pmsm_hil.gap.record import SteadyRecord

Z95 = 1.96  # the 95 % intervals: fitted value +- Z95 standard errors
# Are the constants constant? The fit is repeated on the operating points below and above the
# median current magnitude (each half at least HALF_MIN points); Ld or Lq that differ between the
# halves by more than CURRENT_REL and CURRENT_Z standard errors depend on the current
# (saturation), and the constant values describe neither half. Those fits carry a d-axis voltage
# in proportion to speed (-w psi_q0: psi_q at zero current, or an angle offset), which a measured
# map can hold (the SEW CM3C80S map of ../shared/data/real/: psi_q(0, 0) = -6 mWb) and which
# otherwise goes into Lq, most at small current.
HALF_MIN = 8
CURRENT_REL = 0.10
CURRENT_Z = 3.0
# that d-axis speed voltage is named on all the points when beyond D_EMF_Z standard errors and
# D_EMF_REL of psi_f
D_EMF_Z, D_EMF_REL = 3.0, 0.01

# the parts of a control-rate diagnosis that steady-state dq data cannot give, with the reason
NOT_ASSESSED = {
    "effects": "steady-state dq data: the library's effects (dead time, delay, saturation, ...) are "
    "fitted to the one-step residual of control-rate data; only the parametric gap is assessed",
    "residual_maps": "steady-state dq data: no one-step residual, so no residual maps or order "
    "spectrum",
    "discretisation_gap": "steady-state dq data: no one-step prediction (Euler vs RK4)",
    "noise_floor": "steady-state dq data: no sensor noise model; the base gap is the voltage "
    "equations' rms residual",
    "fitted_rig": "no effect is fitted on steady-state data: the parametric values belong in the "
    "motor file",
}


def parameter_text(p: dict) -> str:
    """R, Ld, Lq, psi_f with their units and 95 % intervals (the parametric gap of steady data)."""
    iv = p.get("interval_95") or {}
    parts = []
    for key, name, unit, scale in (
        ("r_s_ohm", "R", "ohm", 1.0),
        ("l_d_h", "Ld", "mH", 1e3),
        ("l_q_h", "Lq", "mH", 1e3),
        ("psi_f_wb", "psi_f", "Wb", 1.0),
    ):
        v, lo_hi = p[key] * scale, iv.get(key)
        if lo_hi:
            lo, hi = lo_hi[0] * scale, lo_hi[1] * scale
            # enough digits that the interval's ends differ from the value (2 of the half-width)
            ratio = max(abs(v), 1e-300) / max((hi - lo) / 2, 1e-300)
            digits = min(max(3, int(np.ceil(np.log10(ratio))) + 2), 8)
            parts.append(f"{name} {v:.{digits}g} {unit} [{lo:.{digits}g}, {hi:.{digits}g}]")
        else:
            parts.append(f"{name} {v:.4g} {unit}")
    return ", ".join(parts) + f" (95 % intervals; closure {p['closure']:.2f})"


def _fit(idd, iq, w, ud, uq, d_emf: bool = False):
    """Least squares of the steady voltage equations: (x, se, mse, rank) with x = R, Ld, Lq, psi_f
    (and psi_q0, the d-axis speed voltage's flux, with ``d_emf``)."""
    z = np.zeros_like(w)
    A = np.vstack([np.stack([idd, z, -w * iq, z], 1), np.stack([iq, w * idd, z, w], 1)])
    if d_emf:
        A = np.hstack([A, np.concatenate([-w, z])[:, None]])
    y = np.concatenate([ud, uq])
    x, _, rank, _ = np.linalg.lstsq(A, y, rcond=None)
    res = y - A @ x
    dof = max(len(y) - A.shape[1], 1)
    cov = (res @ res / dof) * np.linalg.pinv(A.T @ A)
    se = np.sqrt(np.maximum(np.diag(cov), 0))
    return x, se, float(np.mean(res**2)), int(rank)


def current_dependence(
    idd: np.ndarray, iq: np.ndarray, w: np.ndarray, ud: np.ndarray, uq: np.ndarray
) -> dict | None:
    """Ld and Lq fitted below and above the median current magnitude (with the d-axis speed
    voltage): {"split_a", "below", "above", "changed"}; None when a half is too small or cannot
    give every parameter."""
    mag = np.hypot(idd, iq)
    split = float(np.median(mag))
    halves = []
    for k in (mag <= split, mag > split):
        if k.sum() < HALF_MIN:
            return None
        x, se, _, rank = _fit(idd[k], iq[k], w[k], ud[k], uq[k], d_emf=True)
        if rank < len(x):
            return None
        halves.append((x, se))
    (xl, sl), (xh, sh) = halves
    changed = []
    for j, key in ((1, "l_d_h"), (2, "l_q_h")):
        diff = abs(xh[j] - xl[j])
        if diff > CURRENT_REL * max(abs(xl[j]), abs(xh[j])) and diff > CURRENT_Z * np.hypot(
            sl[j], sh[j]
        ):
            changed.append(key)
    return {
        "split_a": split,
        "below": {"l_d_h": float(xl[1]), "l_q_h": float(xl[2])},
        "above": {"l_d_h": float(xh[1]), "l_q_h": float(xh[2])},
        "changed": changed,
    }


def _dependence_text(dep: dict) -> str:
    names = {"l_d_h": "Ld", "l_q_h": "Lq"}
    parts = [
        f"{names[k]} {dep['below'][k] * 1e3:.3g} mH at |i| <= {dep['split_a']:.3g} A, "
        f"{dep['above'][k] * 1e3:.3g} mH above"
        for k in dep["changed"]
    ]
    return (
        f"; {' and '.join(parts)}: the inductances depend on the current (saturation), the constant "
        "values describe neither; a flux map (docs/rigs.md) or control-rate data"
    )


def diagnose_steady(rec: SteadyRecord, m: MotorModel) -> dict:
    idd, iq = rec.i_dq[:, 0], rec.i_dq[:, 1]
    w = rec.omega_e_rad_s
    ud, uq = rec.u_dq[:, 0], rec.u_dq[:, 1]
    rd = ud - (m.r_s_ohm * idd - w * m.l_q_h * iq)
    rq = uq - (m.r_s_ohm * iq + w * (m.l_d_h * idd + m.psi_f_wb))
    # best constant parameters: unknowns R, Ld, Lq, psi_f (linear)
    x, se, par, _ = _fit(idd, iq, w, ud, uq)
    base = float(np.mean(np.concatenate([rd, rq]) ** 2))
    closure = (base - par) / base if base > 0 else 0.0
    half = Z95 * se
    fitted = {"r_s_ohm": x[0], "l_d_h": x[1], "l_q_h": x[2], "psi_f_wb": x[3]}
    pg: dict[str, object] = {
        **{k: float(v) for k, v in fitted.items()},
        "se": [float(s) for s in se],
        "interval_95": {
            k: [float(v - h), float(v + h)] for (k, v), h in zip(fitted.items(), half, strict=True)
        },
        "motor_file": {
            "r_s_ohm": m.r_s_ohm,
            "l_d_h": m.l_d_h,
            "l_q_h": m.l_q_h,
            "psi_f_wb": m.psi_f_wb,
        },
        "mse_after_v2": par,
        "closure": closure,
    }
    out: dict[str, object] = {
        "source": rec.source,
        "samples": len(w),
        "kind": "steady-state dq",
        "base_gap": {"mse_v2": base, "rms_v": float(np.sqrt(base))},
        "parametric_gap": pg,
        "selected": [],
        # what the steady-state analysis does not assess, and why (the report states it)
        "not_assessed": dict(NOT_ASSESSED),
    }
    dep = current_dependence(idd, iq, w, ud, uq)
    if dep is not None:
        out["current_dependence"] = dep
    x5, se5, _, rank5 = _fit(idd, iq, w, ud, uq, d_emf=True)
    if rank5 == 5 and abs(x5[4]) > D_EMF_Z * se5[4] and abs(x5[4]) > D_EMF_REL * abs(m.psi_f_wb):
        out["d_axis_emf"] = {
            "psi_q0_wb": float(x5[4]),
            "interval_95": [float(x5[4] - Z95 * se5[4]), float(x5[4] + Z95 * se5[4])],
            "angle_offset_rad": float(abs(x5[4]) / max(abs(x5[3]), 1e-12)),
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
    verdict = (
        "parametric gap (steady-state data; effects need control-rate data)"
        if closure > 0.5
        else "no structural gap found (steady-state data)"
    )
    # the verdict carries the fitted values: it is the line `pmsm-hil gap` prints for such data
    saturating = _dependence_text(dep) if dep and dep["changed"] else ""
    out["verdict"] = f"{verdict}: {parameter_text(pg)}{saturating}"
    return out
