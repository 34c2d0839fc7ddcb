/* The plant's magnetics (internal to the plant's files): currents and angle -> flux linkages,
 * inverse incremental inductances, d(psi)/d(theta), extra torque; flux map (plant_map.c), flux
 * harmonics, cogging. The one place for the rig's magnetic effects. Inline: the integrator
 * (plant_integ.h) evaluates them at every RK4 stage. */
#ifndef PLANT_MAG_H
#define PLANT_MAG_H

#include "plant_internal.h"

#include <stddef.h>

/* cos, sin of k times the angle (c, s), k >= 1, by binary powering (no libm) */
PL_INLINE void cpow_k(double c, double s, int k, double *ck, double *sk)
{
    double rc = 1.0, rs = 0.0, t;
    while (k > 0) {
        if (k & 1) {
            t = rc * c - rs * s;
            rs = rs * c + rc * s;
            rc = t;
        }
        k >>= 1;
        if (k > 0) {
            t = c * c - s * s;
            s = 2.0 * c * s;
            c = t;
        }
    }
    *ck = rc;
    *sk = rs;
}

/* General magnetics: flux map (or linear), flux harmonics, cogging. */
PL_INLINE void mag_gen(const plant_t *p, double id, double iq, double c, double s, plant_mag_t *m)
{
    double l[4] = { 0.0, 0.0, 0.0, 0.0 }, det;
    m->dpsi_d_dth_wb = 0.0;
    m->dpsi_q_dth_wb = 0.0;
    m->t_extra_nm = 0.0;
    if (p->cfg.map != NULL) {
        if (p->map_memo_ok && id == p->map_memo_id && iq == p->map_memo_iq) {
            /* the same evaluation, done at the end of the last period (pl_apparent_ld_step) */
            m->psi_d_wb = p->map_memo_pd;
            m->psi_q_wb = p->map_memo_pq;
            memcpy(l, p->map_memo_l, sizeof l);
        } else {
            map_eval(p->cfg.map, id, iq, &m->psi_d_wb, &m->psi_q_wb, l);
        }
        m->psi_d_wb += p->psi_shift_wb;
    } else {
        m->psi_d_wb = p->l_d_h * id + p->psi_f_wb;
        m->psi_q_wb = p->l_q_h * iq;
        l[0] = p->l_d_h;
        l[1] = 0.0;
        l[2] = 0.0;
        l[3] = p->l_q_h;
    }
    if (p->cfg.psi5_rel != 0.0 || p->cfg.psi7_rel != 0.0) {
        /* magnet flux with a 5th (backwards) and 7th harmonic in the stator frame:
         * psi_ab = psi_f (e^{j th} + k5 e^{-j5 th} + k7 e^{j7 th}) -> rotor frame: psi_f (1 + k5 e^{-j6 th} + k7 e^{j6 th}) */
        const double c2 = c * c - s * s, s2 = 2.0 * c * s;
        const double c3 = c2 * c - s2 * s, s3 = s2 * c + c2 * s;
        const double c6 = c3 * c3 - s3 * s3, s6 = 2.0 * c3 * s3;
        const double a = p->psi_f_wb * (p->cfg.psi5_rel + p->cfg.psi7_rel);
        const double b = p->psi_f_wb * (p->cfg.psi7_rel - p->cfg.psi5_rel);
        m->psi_d_wb += a * c6;
        m->psi_q_wb += b * s6;
        m->dpsi_d_dth_wb = -6.0 * a * s6;
        m->dpsi_q_dth_wb = 6.0 * b * c6;
        /* torque of the angle-dependent magnet flux: 1.5 p i . d(psi)/d(theta_e) */
        m->t_extra_nm =
            1.5 * (double)p->cfg.pole_pairs * (id * m->dpsi_d_dth_wb + iq * m->dpsi_q_dth_wb);
    }
    m->l_dd = l[0];
    m->l_dq = l[1];
    m->l_qd = l[2];
    m->l_qq = l[3];
    det = 1.0 / (l[0] * l[3] - l[1] * l[2]);
    m->g_dd = l[3] * det;
    m->g_dq = -l[1] * det;
    m->g_qd = -l[2] * det;
    m->g_qq = l[0] * det;
}

/* Cogging torque at the electrical angle (c, s): T = cog_nm sin(k theta_e + phase), k = cog_order_e.
 * The integrator evaluates it once per sub-step, at the sub-step's mid angle (midpoint rule: relative
 * error (k w_e h)^2 / 24, 0.6 % at 1000 r/min for k = 18 and h = 50 us); the truth exactly. */
PL_INLINE double cog_torque(const plant_t *p, double c, double s)
{
    double ck, sk;
    if (p->cfg.cog_nm == 0.0) {
        return 0.0;
    }
    cpow_k(c, s, p->cfg.cog_order_e, &ck, &sk);
    return p->cfg.cog_nm * (sk * p->cog_c + ck * p->cog_s);
}

/* Flux linkages and inverse incremental inductances at (i_d, i_q) and electrical angle (c = cos, s = sin).
 * mm = 0: the linear IPMSM (no effect on; the compiler specialises the callers, so the effects cost
 * nothing when off); mm = 1: mag_gen() with saturation, flux harmonics, cogging. The voltage equations
 * in deriv() use the general form u = R i + L_inc di/dt + w_e (dpsi/dtheta - J psi). */
PL_INLINE void mag_eval(const plant_t *p, int mm, double id, double iq, double c, double s,
                        plant_mag_t *m)
{
    if (mm) {
        mag_gen(p, id, iq, c, s, m);
        return;
    }
    m->psi_d_wb = p->l_d_h * id + p->psi_f_wb;
    m->psi_q_wb = p->l_q_h * iq;
    m->g_dd = p->inv_l_d;
    m->g_dq = 0.0;
    m->g_qd = 0.0;
    m->g_qq = p->inv_l_q;
    m->dpsi_d_dth_wb = 0.0;
    m->dpsi_q_dth_wb = 0.0;
    m->t_extra_nm = 0.0;
    m->l_dd = p->l_d_h;
    m->l_dq = 0.0;
    m->l_qd = 0.0;
    m->l_qq = p->l_q_h;
}

/* Magnetics with the iron loss: the iron-loss current i_fe = e / R_fe (e: the speed voltage) bypasses
 * the magnetising branch, so flux and torque follow i_m = i - i_fe (one fixed-point step from i,
 * error ~ (w L / R_fe)^2). Returns i_m in *idm, *iqm. */
PL_INLINE void mag_at(const plant_t *p, int mm, double id, double iq, double we, double c, double s,
                      plant_mag_t *m, double *idm, double *iqm)
{
    mag_eval(p, mm, id, iq, c, s, m);
    *idm = id;
    *iqm = iq;
    if (mm && p->inv_r_fe > 0.0) {
        /* i_fe = e / R_fe; psi(i_m) to first order in i_fe (|i_fe| is a few per cent of |i|: the
         * neglected term is 0.5 i_fe . dL/di . i_fe), the incremental inductances at i */
        const double ifd = -we * (m->psi_q_wb - m->dpsi_d_dth_wb) * p->inv_r_fe;
        const double ifq = we * (m->psi_d_wb + m->dpsi_q_dth_wb) * p->inv_r_fe;
        *idm = id - ifd;
        *iqm = iq - ifq;
        m->psi_d_wb -= m->l_dd * ifd + m->l_dq * ifq;
        m->psi_q_wb -= m->l_qd * ifd + m->l_qq * ifq;
    }
}

PL_INLINE double torque_of(const plant_t *p, double id, double iq, const plant_mag_t *m)
{
    return 1.5 * (double)p->cfg.pole_pairs * (m->psi_d_wb * iq - m->psi_q_wb * id) + m->t_extra_nm;
}

#endif
