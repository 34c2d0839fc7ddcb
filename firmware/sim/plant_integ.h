/* The plant's integration (internal to the plant's files): the dq voltage equations and the
 * mechanics at one RK4 stage (deriv), Coulomb friction, and the RK4 step; inline, shared by the
 * switching periods (plant_integ.c) and the PWM-off diode bridge (plant_inverter.c). */
#ifndef PLANT_INTEG_H
#define PLANT_INTEG_H

#include "plant_mag.h"

/* unit vectors of the phase axes in the stationary frame (amplitude-invariant Clarke: i_x = e_x . i_ab) */
static const double EX[3] = { 1.0, -0.5, -0.5 };
static const double EY[3] = { 0.0, PL_SQRT3_2, -PL_SQRT3_2 };

typedef struct {
    double c0, s0; /* cos, sin theta_e at the start of the current sub-step (the angle reference) */
    double u1, u2; /* known voltage: (alpha, beta) in the stationary frame, or (d, q) in MODE_UDQ */
    double t_load;
    double fric;  /* signed Coulomb torque opposing the motion (0 when stuck or frozen) */
    double t_cog; /* cogging torque over the sub-step (rk4(), at the mid angle) */
    int frozen;   /* speed not integrated: stuck in static friction, or held */
    int blocked;  /* MODE_ONE_BLOCKED: index of the open phase */
    double lam;   /* MODE_ONE_BLOCKED: multiplier of the last evaluation (v_x = 1.5 lam) */
} ctx_t;

/* state within a period: currents, speed, and the mechanical angle relative to the sub-step start
 * (0 between sub-steps: rk4() moves the context's angle reference c0, s0 forward instead) */
typedef struct {
    double id, iq, w, th;
} xs_t;

typedef struct {
    double did, diq, dw, dth, ud, uq;
} dx_t;

/* angle of an RK4 stage: cos, sin of theta_e at the mechanical angle th (relative to the sub-step
 * start), from the start speed; each stage corrects it by its own small deviation */
typedef struct {
    double c, s, th;
} base_t;

/* cos, sin of theta_e at an RK4 stage (mechanical angle th relative to the sub-step start) and the
 * known voltage in the rotor frame there */
PL_INLINE void stage_angle_u(const ctx_t *k, double pp, double th, const base_t *b, int first,
                             int mode, double *c, double *s, double *ud, double *uq)
{
    if (first) { /* the first stage sits at the sub-step start */
        *c = b->c;
        *s = b->s;
    } else { /* e = p (th - th_base) ~ p h^2 dw/dt / 4 is tiny: second order is exact to 1e-16 */
        const double e = pp * (th - b->th);
        *c = b->c - e * (b->s + 0.5 * e * b->c);
        *s = b->s + e * (b->c - 0.5 * e * b->s);
    }
    if (mode == MODE_UDQ) {
        *ud = k->u1;
        *uq = k->u2;
    } else { /* stationary-frame voltage seen in the rotor frame */
        *ud = *c * k->u1 + *s * k->u2;
        *uq = -*s * k->u1 + *c * k->u2;
    }
}

/* the stage angles of a step of h at the start speed w: half step, and full step by the
 * double-angle formula (one small-angle rotation, no libm below 0.15 rad per half step) */
PL_INLINE void stage_bases(const ctx_t *k, double pp, double h, double w, base_t *b1, base_t *b2,
                           base_t *b4)
{
    const double h2 = 0.5 * h;
    double cd, sd, c2, s2;
    rot_small(pp * h2 * w, &cd, &sd);
    c2 = cd * cd - sd * sd;
    s2 = 2.0 * cd * sd;
    b1->c = k->c0;
    b1->s = k->s0;
    b1->th = 0.0;
    b2->c = k->c0 * cd - k->s0 * sd;
    b2->s = k->s0 * cd + k->c0 * sd;
    b2->th = h2 * w;
    b4->c = k->c0 * c2 - k->s0 * s2;
    b4->s = k->s0 * c2 + k->c0 * s2;
    b4->th = h * w;
}

/* new angle reference after a step that turned the rotor by dth: the full-step base rotated by the
 * step's own deviation (third order) */
PL_INLINE void step_angle_end(ctx_t *k, double pp, double dth, const base_t *b4, double *th_tot)
{
    const double e = pp * (dth - b4->th);
    const double e2 = 1.0 - 0.5 * e * e;
    const double e3 = e * (1.0 - e * e * (1.0 / 6.0));
    k->c0 = b4->c * e2 - b4->s * e3;
    k->s0 = b4->s * e2 + b4->c * e3;
    *th_tot += dth;
}

PL_INLINE void deriv(const plant_t *p, ctx_t *k, const xs_t *x, dx_t *dx, int mode, int mm,
                     const base_t *b, int first)
{
    const double pp = (double)p->cfg.pole_pairs;
    double c, s, ud, uq, we, rd, rq, te, idm, iqm;
    plant_mag_t m;

    stage_angle_u(k, pp, x->th, b, first, mode, &c, &s, &ud, &uq);
    we = pp * x->w;
    mag_at(p, mm, x->id, x->iq, we, c, s, &m, &idm, &iqm);
    /* L_inc di/dt = u - R i + w_e (J psi - dpsi/dtheta),  J psi = (psi_q, -psi_d) */
    rd = ud - p->r_s_ohm * x->id + we * (m.psi_q_wb - m.dpsi_d_dth_wb);
    rq = uq - p->r_s_ohm * x->iq - we * (m.psi_d_wb + m.dpsi_q_dth_wb);
    if (mode == MODE_ONE_BLOCKED) {
        /* open phase x: its terminal floats so that d(i_x)/dt = 0, where i_x = g . i_dq with
         * g = R(-theta_e) e_x, so d(i_x)/dt = g . (di/dt + w_e J' i), J' i = (-i_q, i_d);
         * the floating terminal adds lam * g to u_dq (lam = 2/3 of its voltage). */
        const double ex = EX[k->blocked], ey = EY[k->blocked];
        const double gd = c * ex + s * ey, gq = -s * ex + c * ey;
        const double ggd = m.g_dd * gd + m.g_qd * gq, ggq = m.g_dq * gd + m.g_qq * gq; /* G^T g */
        const double gGf = ggd * rd + ggq * rq;
        const double gGg = ggd * gd + ggq * gq;
        const double gJi = -gd * x->iq + gq * x->id;
        const double lam = -(gGf + we * gJi) / gGg;
        k->lam = lam;
        rd += lam * gd;
        rq += lam * gq;
        ud += lam * gd;
        uq += lam * gq;
    }
    if (mode == MODE_ALL_BLOCKED) {
        dx->did = 0.0;
        dx->diq = 0.0;
        ud -= rd; /* the terminals float: the motor's terminals show its own back-EMF */
        uq -= rq;
    } else {
        dx->did = m.g_dd * rd + m.g_dq * rq;
        dx->diq = m.g_qd * rd + m.g_qq * rq;
    }
    te = torque_of(p, idm, iqm, &m);
    if (mm) {
        te += k->t_cog;
    }
    dx->dw = k->frozen ? 0.0 : (te - k->t_load - p->cfg.b_visc_nms * x->w - k->fric) * p->inv_j;
    dx->dth = x->w;
    dx->ud = ud;
    dx->uq = uq;
}

/* Coulomb friction for one sub-step (Karnopp): sticks at w = 0 while |T_e - T_load| <= T_c. */
PL_INLINE void mech_mode(const plant_t *p, ctx_t *k, const xs_t *x, int mm)
{
    const double tc = p->cfg.t_coulomb_nm;
    k->fric = 0.0;
    k->frozen = p->hold_speed;
    if (p->hold_speed || !(tc > 0.0)) {
        return;
    }
    if (x->w > 0.0) {
        k->fric = tc;
    } else if (x->w < 0.0) {
        k->fric = -tc;
    } else {
        double td;
        plant_mag_t m;
        mag_eval(p, mm, x->id, x->iq, k->c0, k->s0, &m);
        td = torque_of(p, x->id, x->iq, &m) + (mm ? cog_torque(p, k->c0, k->s0) : 0.0) - k->t_load;
        if (fabs(td) <= tc) {
            k->frozen = 1;
        } else {
            k->fric = td > 0.0 ? tc : -tc;
        }
    }
}

/* after a sub-step: dry friction stops a reversal at zero (breakaway is decided at the next sub-step) */
PL_INLINE void mech_clamp(const ctx_t *k, xs_t *x)
{
    if (x->w * k->fric < 0.0) {
        x->w = 0.0;
    }
}

/* Classic RK4 over h (x->th == 0 on entry). Accumulates the integral of u_dq (for the truth) and
 * moves the context's angle reference to the end of the step: x->th back to 0, the step's angle
 * added to *th_tot. One small-angle rotation per step, no libm call below 0.15 rad per half step. */
PL_INLINE void rk4(const plant_t *p, ctx_t *k, xs_t *x, double h, int mode, int mm, double *aud,
                   double *auq, double *th_tot)
{
    dx_t k1, k2, k3, k4;
    xs_t y;
    base_t b1, b2, b4;
    const double pp = (double)p->cfg.pole_pairs;
    const double h2 = 0.5 * h, h6 = h * (1.0 / 6.0);
    double dth;

    stage_bases(k, pp, h, x->w, &b1, &b2, &b4);
    if (mm) {
        k->t_cog = cog_torque(p, b2.c, b2.s);
    }

    deriv(p, k, x, &k1, mode, mm, &b1, 1);
    y.id = x->id + h2 * k1.did;
    y.iq = x->iq + h2 * k1.diq;
    y.w = x->w + h2 * k1.dw;
    y.th = h2 * k1.dth;
    deriv(p, k, &y, &k2, mode, mm, &b2, 0);
    y.id = x->id + h2 * k2.did;
    y.iq = x->iq + h2 * k2.diq;
    y.w = x->w + h2 * k2.dw;
    y.th = h2 * k2.dth;
    deriv(p, k, &y, &k3, mode, mm, &b2, 0);
    y.id = x->id + h * k3.did;
    y.iq = x->iq + h * k3.diq;
    y.w = x->w + h * k3.dw;
    y.th = h * k3.dth;
    deriv(p, k, &y, &k4, mode, mm, &b4, 0);
    x->id += h6 * (k1.did + 2.0 * (k2.did + k3.did) + k4.did);
    x->iq += h6 * (k1.diq + 2.0 * (k2.diq + k3.diq) + k4.diq);
    x->w += h6 * (k1.dw + 2.0 * (k2.dw + k3.dw) + k4.dw);
    dth = h6 * (k1.dth + 2.0 * (k2.dth + k3.dth) + k4.dth);
    *aud += h6 * (k1.ud + 2.0 * (k2.ud + k3.ud) + k4.ud);
    *auq += h6 * (k1.uq + 2.0 * (k2.uq + k3.uq) + k4.uq);
    step_angle_end(k, pp, dth, &b4, th_tot);
    x->th = 0.0;
}

/* ------------------------------------------------------------------ flux-linkage form (flux maps)
 *
 * With a flux map the voltage equations L_inc(i) di/dt = u - R i + w_e (J psi - dpsi/dtheta) have
 * a right-hand side whose Jacobian L_inc^-1 jumps in slope at every cell boundary (C1 patches), so
 * RK4 in the currents loses its order where the current crosses cells. Integrated in the flux
 * linkage lam = psi_map(i) + psi_shift + harmonics(theta) (the same equations: d lam/dt = L_inc di/dt
 * + w_e d(harmonics)/dtheta), d lam/dt = u - R i + w_e J psi is smooth in lam except through R i,
 * and one RK4 step per period meets the map's voltage equation better than four steps in the
 * currents did (docs/plant.md). Each stage recovers i from lam by one Newton step from a linear
 * predictor (the map evaluation the stage needs anyway: psi and Gamma at the predicted current);
 * the step's end by Newton steps until the correction is below PL_LAM_TOL_A. */

typedef struct {
    double ld, lq, w, th;
} xl_t;

/* one stage: *id, *iq in: the predicted current, out: the Newton-corrected one; *g: Gamma there */
PL_INLINE void deriv_lam(const plant_t *p, ctx_t *k, xl_t *x, double *id, double *iq, double g[4],
                         dx_t *dx, int mode, const base_t *b, int first)
{
    const double pp = (double)p->cfg.pole_pairs;
    double c, s, ud, uq, we, te, idm, iqm, psd, psq;
    plant_mag_t m;

    stage_angle_u(k, pp, x->th, b, first, mode, &c, &s, &ud, &uq);
    we = pp * x->w;
    mag_gen(p, *id, *iq, c, s, &m);
    if (first) { /* the stage at the known current: lam = psi(i) */
        x->ld = m.psi_d_wb;
        x->lq = m.psi_q_wb;
    } else { /* Newton: i += Gamma (lam - psi(i)) */
        const double ed = x->ld - m.psi_d_wb, eq = x->lq - m.psi_q_wb;
        *id += m.g_dd * ed + m.g_dq * eq;
        *iq += m.g_qd * ed + m.g_qq * eq;
    }
    g[0] = m.g_dd;
    g[1] = m.g_dq;
    g[2] = m.g_qd;
    g[3] = m.g_qq;
    psd = x->ld;
    psq = x->lq;
    idm = *id;
    iqm = *iq;
    if (p->inv_r_fe >
        0.0) { /* iron loss as mag_at(), the incremental inductances at the predictor */
        const double ifd = -we * (psq - m.dpsi_d_dth_wb) * p->inv_r_fe;
        const double ifq = we * (psd + m.dpsi_q_dth_wb) * p->inv_r_fe;
        idm = *id - ifd;
        iqm = *iq - ifq;
        psd -= m.l_dd * ifd + m.l_dq * ifq;
        psq -= m.l_qd * ifd + m.l_qq * ifq;
    }
    dx->did = ud - p->r_s_ohm * *id + we * psq; /* d lam_d / dt */
    dx->diq = uq - p->r_s_ohm * *iq - we * psd; /* d lam_q / dt */
    te = 1.5 * pp * (psd * iqm - psq * idm) +
         1.5 * pp * (*id * m.dpsi_d_dth_wb + *iq * m.dpsi_q_dth_wb) + k->t_cog;
    dx->dw = k->frozen ? 0.0 : (te - k->t_load - p->cfg.b_visc_nms * x->w - k->fric) * p->inv_j;
    dx->dth = x->w;
    dx->ud = ud;
    dx->uq = uq;
}

/* i += Gamma dlam */
PL_INLINE void lam_predict(double *id, double *iq, const double g[4], double dld, double dlq)
{
    *id += g[0] * dld + g[1] * dlq;
    *iq += g[2] * dld + g[3] * dlq;
}

/* the next stage's state l0 + a k, and its current predicted from the last stage's by Gamma dlam */
PL_INLINE void lam_next(xl_t *y, const xl_t *l0, double a, const dx_t *kp, double *id, double *iq,
                        const double g[4])
{
    const double pld = y->ld, plq = y->lq;
    y->ld = l0->ld + a * kp->did;
    y->lq = l0->lq + a * kp->diq;
    y->w = l0->w + a * kp->dw;
    y->th = a * kp->dth;
    lam_predict(id, iq, g, y->ld - pld, y->lq - plq);
}

/* The step's end: Newton until |correction| < PL_LAM_TOL_A (the error left is then ~ the map's
 * curvature times its square, < 1e-7 A), at most PL_LAM_NEWTON_MAX evaluations (one, mostly). */
#define PL_LAM_TOL_A      1e-3
#define PL_LAM_NEWTON_MAX 3

/* RK4 over h in the flux linkage (x->th == 0 on entry; MODE_KNOWN or MODE_UDQ), as rk4()
 * otherwise; x->id, x->iq: the currents at the start, replaced by those at the end. */
PL_INLINE void rk4_lam(const plant_t *p, ctx_t *k, xs_t *x, double h, int mode, double *aud,
                       double *auq, double *th_tot)
{
    dx_t k1, k2, k3, k4;
    xl_t y, l0;
    base_t b1, b2, b4;
    const double pp = (double)p->cfg.pole_pairs;
    const double h2 = 0.5 * h, h6 = h * (1.0 / 6.0);
    double dth, id, iq, g[4], lde, lqe;
    int n;

    stage_bases(k, pp, h, x->w, &b1, &b2, &b4);
    k->t_cog = cog_torque(p, b2.c, b2.s);

    l0.ld = 0.0; /* set by the first stage */
    l0.lq = 0.0;
    l0.w = x->w;
    l0.th = 0.0;
    id = x->id;
    iq = x->iq;
    deriv_lam(p, k, &l0, &id, &iq, g, &k1, mode, &b1, 1);
    y = l0;
    lam_next(&y, &l0, h2, &k1, &id, &iq, g);
    deriv_lam(p, k, &y, &id, &iq, g, &k2, mode, &b2, 0);
    lam_next(&y, &l0, h2, &k2, &id, &iq, g);
    deriv_lam(p, k, &y, &id, &iq, g, &k3, mode, &b2, 0);
    lam_next(&y, &l0, h, &k3, &id, &iq, g);
    deriv_lam(p, k, &y, &id, &iq, g, &k4, mode, &b4, 0);
    lde = l0.ld + h6 * (k1.did + 2.0 * (k2.did + k3.did) + k4.did);
    lqe = l0.lq + h6 * (k1.diq + 2.0 * (k2.diq + k3.diq) + k4.diq);
    x->w += h6 * (k1.dw + 2.0 * (k2.dw + k3.dw) + k4.dw);
    dth = h6 * (k1.dth + 2.0 * (k2.dth + k3.dth) + k4.dth);
    *aud += h6 * (k1.ud + 2.0 * (k2.ud + k3.ud) + k4.ud);
    *auq += h6 * (k1.uq + 2.0 * (k2.uq + k3.uq) + k4.uq);
    step_angle_end(k, pp, dth, &b4, th_tot);
    x->th = 0.0;
    /* the currents at the end: Newton on psi(i) = lam at the end angle */
    lam_predict(&id, &iq, g, lde - y.ld, lqe - y.lq);
    for (n = 0; n < PL_LAM_NEWTON_MAX; n++) {
        plant_mag_t m;
        double ed, eq, nd, nq;
        mag_gen(p, id, iq, k->c0, k->s0, &m);
        ed = lde - m.psi_d_wb;
        eq = lqe - m.psi_q_wb;
        nd = m.g_dd * ed + m.g_dq * eq;
        nq = m.g_qd * ed + m.g_qq * eq;
        id += nd;
        iq += nq;
        if (fabs(nd) + fabs(nq) < PL_LAM_TOL_A) {
            break;
        }
    }
    x->id = id;
    x->iq = iq;
}

/* plant_integ.c */
void pl_ctx_start(const plant_t *p, ctx_t *k, xs_t *x, double t_load);
void pl_finish_period(plant_t *p, const ctx_t *k, const xs_t *x, double th_tot, double aud,
                      double auq);
void pl_advance_on(plant_t *p, int mode, double u1, double u2, double t_load);
void pl_hist_fill(plant_t *p);

/* plant_thermal.c */
void pl_losses(const plant_t *p, double *p_cu, double *p_fe);
void pl_thermal_params(plant_t *p);
void pl_thermal_step(plant_t *p);
void pl_apparent_ld_step(plant_t *p); /* plant.c: one period of the apparent-L_d fit */
void pl_dc_link_step(plant_t *p, const double d[3], bool pwm_on, const double i0[3]);

/* plant_inverter.c */
void pl_step_legs(plant_t *p, const double d_in[3], bool on_in, bool carrier_in, double t_load);

#endif
