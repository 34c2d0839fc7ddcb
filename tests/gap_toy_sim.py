"""An independent toy simulator for the CSV interface of the gap diagnosis (not the emulator): a
surface-PM motor under dq PI current control with carrier PWM (duties, min-max injection), a hard-
sign averaged dead time, forward Euler with 20 sub-steps, Gaussian current noise. Writes
the control-rate CSV columns of docs/gap.md, "CSV import"."""

from __future__ import annotations

import math

import numpy as np

R, LD, LQ, PSI, P = 0.9, 0.005, 0.012, 0.18, 4


def simulate(path, dead_time_s=0.0, noise_a=0.02, ts=50e-6, t_end=1.0, v_dc=540.0, seed=0, sub=20):
    rng = np.random.default_rng(seed)
    n = round(t_end / ts)
    i_d = i_q = 0.0
    theta = 0.0
    xi_d = xi_q = 0.0
    kp_d, kp_q, ki = LD * 2000, LQ * 2000, R * 2000
    rows = []
    for k in range(n):
        t = k * ts
        seg = int(t / 0.05)
        omega = (150.0, 400.0, -250.0, 600.0)[seg % 4]
        id_ref = (0.0, -3.0)[(seg // 2) % 2]
        iq_ref = (2.0, 8.0, -4.0)[seg % 3]
        c, s = math.cos(theta), math.sin(theta)
        i_al, i_be = c * i_d - s * i_q, s * i_d + c * i_q
        ia = i_al + rng.normal(0, noise_a)
        ib = -0.5 * i_al + math.sqrt(3) / 2 * i_be + rng.normal(0, noise_a)
        # controller on the measured currents
        m_al, m_be = ia, (ia + 2 * ib) / math.sqrt(3)
        md, mq = c * m_al + s * m_be, -s * m_al + c * m_be
        ed, eq = id_ref - md, iq_ref - mq
        xi_d += ki * ed * ts
        xi_q += ki * eq * ts
        ud = kp_d * ed + xi_d - omega * LQ * mq
        uq = kp_q * eq + xi_q + omega * (LD * md + PSI)
        ua, ub = c * ud - s * uq, s * ud + c * uq
        va, vb, vc = ua, -0.5 * ua + math.sqrt(3) / 2 * ub, -0.5 * ua - math.sqrt(3) / 2 * ub
        off = (max(va, vb, vc) + min(va, vb, vc)) / 2
        d = [min(max(0.5 + (v - off) / v_dc, 0.0), 1.0) for v in (va, vb, vc)]
        rows.append((t, ia, ib, d[0], d[1], d[2], v_dc, theta % (2 * math.pi), omega))
        # plant over the period
        h = ts / sub
        for _ in range(sub):
            c, s = math.cos(theta), math.sin(theta)
            i_al, i_be = c * i_d - s * i_q, s * i_d + c * i_q
            iph = (
                i_al,
                -0.5 * i_al + math.sqrt(3) / 2 * i_be,
                -0.5 * i_al - math.sqrt(3) / 2 * i_be,
            )
            pole = [
                dx * v_dc - (dead_time_s / ts) * v_dc * math.copysign(1.0, ix)
                for dx, ix in zip(d, iph, strict=False)
            ]
            u_al = (2 * pole[0] - pole[1] - pole[2]) / 3
            u_be = (pole[1] - pole[2]) / math.sqrt(3)
            u_d, u_q = c * u_al + s * u_be, -s * u_al + c * u_be
            did = (u_d - R * i_d + omega * LQ * i_q) / LD
            diq = (u_q - R * i_q - omega * (LD * i_d + PSI)) / LQ
            i_d += h * did
            i_q += h * diq
            theta += h * omega
    with open(path, "w") as f:
        f.write("t_s,i_a_a,i_b_a,d_a,d_b,d_c,v_dc_v,theta_e_rad,omega_e_rad_s\n")
        for r in rows:
            f.write(",".join(repr(float(x)) for x in r) + "\n")
