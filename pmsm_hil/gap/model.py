"""The nominal model and the one-step current predictor of the gap probe (docs/gap.md, "Probe").

Sample k: currents measured at t_k, voltage u_alpha_beta held over [t_k, t_k+1] (constant in the
stationary frame), rotor at theta_k turning at omega_k. The predictor integrates the dq model over
the period with RK4 (the applied voltage rotated into the rotor frame at every stage), so that its
discretisation error (~(omega Ts)^5) is far below the firmware's forward-Euler one; the difference
between the two on the same data is reported as the discretisation gap.

The residual is in volts-equivalent: r = diag(Ld, Lq) (i_dq,meas(k+1) - i_dq,pred(k+1)) / Ts, the
mean voltage over the period that the model misses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from pmsm_hil.profiles import Motor

SQ3 = np.sqrt(3.0)


@dataclass(frozen=True)
class MotorModel:
    r_s_ohm: float
    l_d_h: float
    l_q_h: float
    psi_f_wb: float
    pole_pairs: int
    j_kgm2: float = 0.0
    b_visc_nms: float = 0.0
    t_coulomb_nm: float = 0.0
    i_max_a: float = 10.0
    v_dc_v: float = 0.0

    @classmethod
    def from_motor(cls, m: Motor) -> MotorModel:
        return cls(
            float(m.r_s_ohm),
            float(m.l_d_h),
            float(m.l_q_h),
            float(m.psi_f_wb),
            int(m.pole_pairs),
            float(getattr(m, "j_kgm2", 0.0) or 0.0),
            float(getattr(m, "b_visc_nms", 0.0) or 0.0),
            float(getattr(m, "t_coulomb_nm", 0.0) or 0.0),
            float(getattr(m, "i_max_a", 10.0) or 10.0),
            float(getattr(m, "v_dc_v", 0.0) or 0.0),
        )


def abc_to_ab(i_abc: np.ndarray) -> np.ndarray:
    """alpha-beta from phases a and b (as the firmware builds it; i_c is not used)."""
    return np.stack([i_abc[..., 0], (i_abc[..., 0] + 2.0 * i_abc[..., 1]) / SQ3], axis=-1)


def rot(x: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """Rotate 2-vectors by ang (ab -> dq with ang = -theta)."""
    c, s = np.cos(ang), np.sin(ang)
    return np.stack([c * x[..., 0] - s * x[..., 1], s * x[..., 0] + c * x[..., 1]], axis=-1)


@dataclass
class PlantTerms:
    """Departures from the nominal plant used by the predictor (all optional)."""

    r_s_ohm: np.ndarray | float | None = None  # resistance in force
    psi_f_wb: np.ndarray | float | None = None  # magnet flux in force
    sat: tuple | None = (
        None  # (k_d, i_sd, k_q, i_sq, k_x, k_c): per-axis depth and knee, cross terms
    )
    g_fe_s: float = 0.0  # iron-loss conductance 1/R_fe
    u_dist_dq: np.ndarray | None = None  # (M, 2) extra voltage over the period, rotor frame
    psi_h_dq: tuple[np.ndarray, np.ndarray] | None = (
        None  # flux harmonic (psi_dq(theta), dpsi_dq/dtheta)
    )


# the incremental inductances' floor, as a fraction of the smaller nominal one: a saturating axis
# of the model keeps at least 0.1 of its own (k <= 0.9, effects.py); the cross terms are held to
# the same (_floored)
L_FLOOR = 0.1


def _sat_axis(l0: float, k: float, i_s: float, i):
    """One axis's saturation: incremental L = L0 (1 - k + k / (1 + (i/i_s)^2)) falls by the fraction k
    beyond the knee current i_s; psi = L0 ((1 - k) i + k i_s atan(i/i_s))."""
    x = i / i_s
    return l0 * (1 - k + k / (1 + x * x)), l0 * ((1 - k) * i + k * i_s * np.arctan(x))


def _flux(m: MotorModel, i: np.ndarray, pt: PlantTerms, psi_f):
    """psi_dq and the incremental inductance matrix (Ldd, Ldq, Lqq) at currents i (M, 2)."""
    id_, iq = i[..., 0], i[..., 1]
    if pt.sat is None:
        return (psi_f + m.l_d_h * id_, m.l_q_h * iq), (m.l_d_h, 0.0, m.l_q_h)
    kd, isd, kq, isq, kx, kc = pt.sat
    ld_inc, psi_d = _sat_axis(m.l_d_h, kd, isd, id_)
    lq_inc, psi_q = _sat_axis(m.l_q_h, kq, isq, iq)
    psi_d = psi_d + psi_f
    i2 = m.i_max_a**2
    lx = kx * np.sqrt(m.l_d_h * m.l_q_h) / i2
    lc = kc * np.sqrt(m.l_d_h * m.l_q_h) / m.i_max_a
    # cross-saturation from the co-energy terms -lx/2 id^2 iq^2 - lc id iq^2 (reciprocal)
    psi_d = psi_d - lx * id_ * iq**2 - lc * iq**2
    psi_q = psi_q - lx * id_**2 * iq - 2 * lc * id_ * iq
    ldd = ld_inc - lx * iq**2
    lqq = lq_inc - lx * id_**2 - 2 * lc * id_
    ldq = -2 * lx * id_ * iq - 2 * lc * iq
    return (psi_d, psi_q), _floored(ldd, ldq, lqq, L_FLOOR * min(m.l_d_h, m.l_q_h))


def _floored(a, b, c, l_min_h: float):
    """The incremental inductance matrix [[a, b], [b, c]] with its eigenvalues raised to l_min_h
    where they are below, its eigenvectors kept (the same values, bit for bit, where both are
    above). The cross terms of a fitted saturation can make the matrix lose positive definiteness
    at large currents; a magnetic circuit's cannot (its co-energy is convex), and the period's
    prediction divides by the matrix's determinant there: one RK4 stage on a SEW CM3C80S record
    crossed into such a region and predicted a 3 kV residual, which one test block's mean could
    not survive (docs/gap.md, "Which")."""
    # Gershgorin: every eigenvalue is at least min(a, c) - |b|; checked on the extremes first,
    # which is enough for almost every evaluation (a fit's saturation seldom comes near the floor)
    if min(np.min(a), np.min(c)) - np.max(np.abs(b)) >= l_min_h:
        return a, b, c
    mid = 0.5 * (a + c)
    rad = np.hypot(0.5 * (a - c), b)
    short = l_min_h - (mid - rad)
    if not np.any(short > 0.0):
        return a, b, c
    lo, hi = np.maximum(short, 0.0), np.maximum(l_min_h - (mid + rad), 0.0)
    # the projector on the smaller eigenvalue's eigenvector, (lam_max I - M) / (2 rad), and on
    # the larger's, I less it; a multiple of the identity (rad = 0) is raised as a whole
    live = rad > 0.0
    two_rad = np.where(live, 2.0 * rad, 1.0)
    pa = np.where(live, (mid + rad - a) / two_rad, 1.0)
    pb = np.where(live, -b / two_rad, 0.0)
    pc = np.where(live, (mid + rad - c) / two_rad, 1.0)
    hi = np.where(live, hi, 0.0)
    return a + lo * pa + hi * (1.0 - pa), b + (lo - hi) * pb, c + lo * pc + hi * (1.0 - pc)


def rot_cs(x: np.ndarray, c: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Rotate 2-vectors by the angle whose cosine and sine are c, s."""
    return np.stack([c * x[..., 0] - s * x[..., 1], s * x[..., 0] + c * x[..., 1]], axis=-1)


def _deriv(m: MotorModel, i, u, omega, pt: PlantTerms, r_s, psi_f):
    if pt.u_dist_dq is not None:
        u = u + pt.u_dist_dq
    (psi_d, psi_q), (ldd, ldq, lqq) = _flux(m, i, pt, psi_f)
    e_d, e_q = -omega * psi_q, omega * psi_d
    if pt.g_fe_s:
        # iron loss: i_fe = e / R_fe flows beside the magnetising current; flux from i - i_fe
        ife_d, ife_q = pt.g_fe_s * e_d, pt.g_fe_s * e_q
        e_d = e_d + omega * (m.l_q_h * ife_q)
        e_q = e_q - omega * (m.l_d_h * ife_d)
    if pt.psi_h_dq is not None:
        ph, dph = pt.psi_h_dq
        e_d = e_d - omega * ph[1] + omega * dph[0]
        e_q = e_q + omega * ph[0] + omega * dph[1]
    v_d = u[..., 0] - r_s * i[..., 0] - e_d
    v_q = u[..., 1] - r_s * i[..., 1] - e_q
    det = ldd * lqq - ldq * ldq
    return np.stack([(lqq * v_d - ldq * v_q) / det, (ldd * v_q - ldq * v_d) / det], axis=-1)


def predict_rk4(
    m: MotorModel,
    i0: np.ndarray,
    theta0: np.ndarray,
    omega: np.ndarray,
    u_ab: np.ndarray,
    ts_s: float,
    pt: PlantTerms | None = None,
    n_sub: int = 1,
    cs0: tuple | None = None,
) -> np.ndarray:
    """i_dq at t_k + Ts from i0 (M, 2) at t_k (RK4, n_sub steps per period); cs0: cos, sin of theta0
    if already known."""
    pt = pt or PlantTerms()
    r_s = m.r_s_ohm if pt.r_s_ohm is None else pt.r_s_ohm
    psi_f = m.psi_f_wb if pt.psi_f_wb is None else pt.psi_f_wb
    h = ts_s / n_sub
    i = np.asarray(i0, float)
    c0, s0 = cs0 if cs0 is not None else (np.cos(theta0), np.sin(theta0))
    u = rot_cs(u_ab, c0, -s0)  # rotor-frame voltage at the period start
    ch, sh = np.cos(0.5 * h * omega), np.sin(0.5 * h * omega)
    for _ in range(n_sub):
        u_mid = rot_cs(u, ch, -sh)
        u_end = rot_cs(u_mid, ch, -sh)
        k1 = _deriv(m, i, u, omega, pt, r_s, psi_f)
        k2 = _deriv(m, i + 0.5 * h * k1, u_mid, omega, pt, r_s, psi_f)
        k3 = _deriv(m, i + 0.5 * h * k2, u_mid, omega, pt, r_s, psi_f)
        k4 = _deriv(m, i + h * k3, u_end, omega, pt, r_s, psi_f)
        i = i + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
        u = u_end
    return i


def predict_euler(
    m: MotorModel,
    i0: np.ndarray,
    theta0: np.ndarray,
    omega: np.ndarray,
    u_ab: np.ndarray,
    ts_s: float,
) -> np.ndarray:
    """The firmware's predictor: forward Euler of the dq model, voltage at the period-start angle."""
    u = rot(u_ab, -theta0)
    d = (u[..., 0] - m.r_s_ohm * i0[..., 0] + omega * m.l_q_h * i0[..., 1]) / m.l_d_h
    q = (u[..., 1] - m.r_s_ohm * i0[..., 1] - omega * (m.l_d_h * i0[..., 0] + m.psi_f_wb)) / m.l_q_h
    return i0 + ts_s * np.stack([d, q], axis=-1)


def volts(m: MotorModel, di: np.ndarray, ts_s: float) -> np.ndarray:
    """A one-step current error (M, 2) in volts-equivalent."""
    return di * np.array([m.l_d_h, m.l_q_h]) / ts_s
