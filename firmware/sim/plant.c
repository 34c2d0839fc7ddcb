/* IPMSM + two-level inverter + sensors + load: the emulator's plant. See plant.h and docs/plant.md.
 *
 * Structure (the seams for the rig effects):
 *   mag_eval()      magnetics: currents (and angle) -> flux linkages, inverse incremental inductances,
 *                   d(psi)/d(theta), extra torque. The one place for saturation, flux harmonics, cogging.
 *   deriv()         the dq voltage equations and the mechanics, evaluated at one RK4 stage.
 *   leg_dist()      inverter distortion voltage per leg (dead time, device drop).
 *   sensor_*()      (plant_sensors.c) phase-current ADC, DC-link voltage, encoder: offsets, gains,
 *                   noise, quantisation.
 *   advance_on()    RK4 over one period with a known stationary-frame (or rotor-frame) voltage.
 *   advance_off()   PWM off: diode bridge with current-zero events.
 */
#include "plant_internal.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

/* unit vectors of the phase axes in the stationary frame (amplitude-invariant Clarke: i_x = e_x . i_ab) */
static const double EX[3] = {1.0, -0.5, -0.5};
static const double EY[3] = {0.0, PL_SQRT3_2, -PL_SQRT3_2};

double plant_sigmoid(double x) { return sigm(x); }

/* ------------------------------------------------------------------ magnetics (effect seam) */

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
    double l[4] = {0.0, 0.0, 0.0, 0.0}, det;
    m->dpsi_d_dth_wb = 0.0;
    m->dpsi_q_dth_wb = 0.0;
    m->t_extra_nm = 0.0;
    if (p->cfg.map != NULL) {
        map_eval(p->cfg.map, id, iq, &m->psi_d_wb, &m->psi_q_wb, l);
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
        m->t_extra_nm = 1.5 * (double)p->cfg.pole_pairs * (id * m->dpsi_d_dth_wb + iq * m->dpsi_q_dth_wb);
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
PL_INLINE void mag_eval(const plant_t *p, int mm, double id, double iq, double c, double s, plant_mag_t *m)
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

void plant_flux(const plant_t *p, double i_d_a, double i_q_a, double theta_e_rad, plant_mag_t *m)
{
    mag_eval(p, p->mag_general ? 1 : 0, i_d_a, i_q_a, cos(theta_e_rad), sin(theta_e_rad), m);
}

double plant_torque(const plant_t *p, double i_d_a, double i_q_a, double theta_e_rad)
{
    plant_mag_t m;
    plant_flux(p, i_d_a, i_q_a, theta_e_rad, &m);
    return torque_of(p, i_d_a, i_q_a, &m) + cog_torque(p, cos(theta_e_rad), sin(theta_e_rad));
}

/* ------------------------------------------------------------------ inverter distortion (effect seam) */

PL_INLINE double leg_dist(const plant_t *p, double i, double rise, double fall, double k_dt_v)
{
    double sg;
    if (p->inv_i_dt <= 0.0) {
        return 0.0;
    }
    sg = sigm(i * p->inv_i_dt);
    /* rise (0 -> 1): the upper switch turns on t_d late; meanwhile i > 0 keeps the lower diode on (volts lost).
     * fall (1 -> 0): the lower switch turns on t_d late; meanwhile i < 0 keeps the upper diode on (volts gained).
     * sigma replaces the ideal sign: a small current cannot swing the leg within the dead time. */
    return -p->cfg.v_drop_v * sg - k_dt_v * (rise * 0.5 * (1.0 + sg) - fall * 0.5 * (1.0 - sg));
}

double plant_leg_distortion_v(const plant_t *p, double i_a, int transition)
{
    const double rise = (transition == 1 || transition == 2) ? 1.0 : 0.0;
    const double fall = (transition == -1 || transition == 2) ? 1.0 : 0.0;
    return leg_dist(p, i_a, rise, fall, p->v_dc_v * p->cfg.dead_time_s / p->cfg.ts_s);
}

/* ------------------------------------------------------------------ dynamics */

typedef struct {
    double c0, s0;      /* cos, sin theta_e at the start of the current sub-step (the angle reference) */
    double u1, u2;      /* known voltage: (alpha, beta) in the stationary frame, or (d, q) in MODE_UDQ */
    double t_load;
    double fric;        /* signed Coulomb torque opposing the motion (0 when stuck or frozen) */
    double t_cog;       /* cogging torque over the sub-step (rk4(), at the mid angle) */
    int frozen;         /* speed not integrated: stuck in static friction, or held */
    int blocked;        /* MODE_ONE_BLOCKED: index of the open phase */
    double lam;         /* MODE_ONE_BLOCKED: multiplier of the last evaluation (v_x = 1.5 lam) */
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

PL_INLINE void deriv(const plant_t *p, ctx_t *k, const xs_t *x, dx_t *dx, int mode, int mm, const base_t *b, int first)
{
    const double pp = (double)p->cfg.pole_pairs;
    double c, s, ud, uq, we, rd, rq, te, idm, iqm;
    plant_mag_t m;

    if (first) {   /* the first stage sits at the sub-step start */
        c = b->c;
        s = b->s;
    } else {       /* e = p (th - th_base) ~ p h^2 dw/dt / 4 is tiny: second order is exact to 1e-16 */
        const double e = pp * (x->th - b->th);
        c = b->c - e * (b->s + 0.5 * e * b->c);
        s = b->s + e * (b->c - 0.5 * e * b->s);
    }
    if (mode == MODE_UDQ) {
        ud = k->u1;
        uq = k->u2;
    } else {       /* stationary-frame voltage seen in the rotor frame */
        ud = c * k->u1 + s * k->u2;
        uq = -s * k->u1 + c * k->u2;
    }
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
        ud -= rd;   /* the terminals float: the motor's terminals show its own back-EMF */
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
PL_INLINE void rk4(const plant_t *p, ctx_t *k, xs_t *x, double h, int mode, int mm, double *aud, double *auq, double *th_tot)
{
    dx_t k1, k2, k3, k4;
    xs_t y;
    base_t b1, b2, b4;
    const double pp = (double)p->cfg.pole_pairs;
    const double h2 = 0.5 * h, h6 = h * (1.0 / 6.0);
    double cd, sd, c2, s2, dth, e, e2, e3;

    /* stage angles at the start speed: half step, and full step by the double-angle formula */
    rot_small(pp * h2 * x->w, &cd, &sd);
    c2 = cd * cd - sd * sd;
    s2 = 2.0 * cd * sd;
    b1.c = k->c0;
    b1.s = k->s0;
    b1.th = 0.0;
    b2.c = k->c0 * cd - k->s0 * sd;
    b2.s = k->s0 * cd + k->c0 * sd;
    b2.th = h2 * x->w;
    b4.c = k->c0 * c2 - k->s0 * s2;
    b4.s = k->s0 * c2 + k->c0 * s2;
    b4.th = h * x->w;
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
    /* new angle reference: the full-step base rotated by the step's own deviation (third order) */
    e = pp * (dth - b4.th);
    e2 = 1.0 - 0.5 * e * e;
    e3 = e * (1.0 - e * e * (1.0 / 6.0));
    k->c0 = b4.c * e2 - b4.s * e3;
    k->s0 = b4.s * e2 + b4.c * e3;
    *th_tot += dth;
    x->th = 0.0;
}

/* copper and iron losses at the present state */
static void losses(const plant_t *p, double *p_cu, double *p_fe)
{
    const double r_fe_inv = p->inv_r_fe > 0.0 ? p->inv_r_fe
                            : (p->cfg.r_fe_heat_ohm > 0.0 ? 1.0 / p->cfg.r_fe_heat_ohm : 0.0);
    *p_cu = 1.5 * p->r_s_ohm * (p->i_d_a * p->i_d_a + p->i_q_a * p->i_q_a);
    *p_fe = 0.0;
    if (r_fe_inv > 0.0) {
        const double we = (double)p->cfg.pole_pairs * p->omega_m_rad_s;
        plant_mag_t m;
        double idm, iqm, ed, eq;
        mag_at(p, p->mag_general ? 1 : 0, p->i_d_a, p->i_q_a, we, p->cos_e, p->sin_e, &m, &idm, &iqm);
        ed = -we * (m.psi_q_wb - m.dpsi_d_dth_wb);
        eq = we * (m.psi_d_wb + m.dpsi_q_dth_wb);
        *p_fe = 1.5 * (ed * ed + eq * eq) * r_fe_inv;
    }
}

/* parameters that follow the temperatures */
static void thermal_params(plant_t *p)
{
    p->r_s_ohm = p->cfg.r_s_ohm * (1.0 + p->cfg.alpha_r_per_k * (p->temp_winding_c - p->cfg.temp_ref_c));
    p->psi_f_wb = p->psi_f_ref_wb * (1.0 + p->cfg.alpha_psi_per_k * (p->temp_magnet_c - p->cfg.temp_ref_c));
    p->psi_shift_wb = p->cfg.map != NULL ? p->psi_f_wb - p->cfg.map->psi_f_wb : 0.0;   /* added to the map's psi_d */
}

/* two-node thermal network, explicit Euler every PLANT_THERMAL_DIV periods (time constants are seconds
 * to minutes) with the copper loss averaged over those periods and the iron loss at their end:
 * C_w dT_w/dt = P_cu + P_fe - (T_w - T_a)/R_wa - (T_w - T_m)/R_wm,  C_m dT_m/dt = (T_w - T_m)/R_wm - (T_m - T_a)/R_ma */
static void thermal_step(plant_t *p)
{
    const double dt = p->cfg.ts_s * (double)PLANT_THERMAL_DIV, ta = p->cfg.temp_ambient_c;
    const double tw = p->temp_winding_c, tm = p->temp_magnet_c;
    const double q_wm = (tw - tm) / p->cfg.r_wm_k_w;
    double p_cu_now;
    losses(p, &p_cu_now, &p->p_fe_w);
    p->p_cu_w = p->th_acc_w * (1.0 / (double)PLANT_THERMAL_DIV);
    p->th_acc_w = 0.0;
    p->th_n = 0;
    p->temp_winding_c = tw + dt * (p->p_cu_w + p->p_fe_w - (tw - ta) / p->cfg.r_wa_k_w - q_wm) / p->cfg.c_winding_j_k;
    p->temp_magnet_c = tm + dt * (q_wm - (tm - ta) / p->cfg.r_ma_k_w) / p->cfg.c_magnet_j_k;
    thermal_params(p);
}

/* true phase currents at the period boundaries, for the sample delay */
static void hist_push(plant_t *p)
{
    p->hist_pos = (p->hist_pos + 1u) & (PLANT_DELAY_RING - 1u);
    phase_currents(p->cos_e, p->sin_e, p->i_d_a, p->i_q_a, p->hist_i[p->hist_pos]);
}

static void hist_fill(plant_t *p)
{
    int n;
    for (n = 0; n < PLANT_DELAY_RING; n++) {
        hist_push(p);
    }
}

/* store the period's end state; cos/sin of the electrical angle are carried incrementally
 * (renormalised every period) and recomputed from theta_m every 256 periods */
static void finish_period(plant_t *p, const ctx_t *k, const xs_t *x, double th_tot, double aud, double auq)
{
    p->i_d_a = x->id;
    p->i_q_a = x->iq;
    p->omega_m_rad_s = x->w;
    p->theta_m_rad = wrap_2pi(p->theta_m_rad + th_tot);
    p->n_periods++;
    if ((p->n_periods & 255u) == 0u) {
        const double the = (double)p->cfg.pole_pairs * p->theta_m_rad;
        p->cos_e = cos(the);
        p->sin_e = sin(the);
    } else {
        const double r = 1.5 - 0.5 * (k->c0 * k->c0 + k->s0 * k->s0);
        p->cos_e = k->c0 * r;
        p->sin_e = k->s0 * r;
    }
    p->u_d_avg_v = aud * p->inv_ts;
    p->u_q_avg_v = auq * p->inv_ts;
    if (p->cfg.thermal_on) {
        p->th_acc_w += 1.5 * p->r_s_ohm * (x->id * x->id + x->iq * x->iq);
        if (++p->th_n >= PLANT_THERMAL_DIV) {
            thermal_step(p);
        }
    }
    if (p->delay_n >= 0) {
        hist_push(p);
    }
}

static void ctx_start(const plant_t *p, ctx_t *k, xs_t *x, double t_load)
{
    k->c0 = p->cos_e;
    k->s0 = p->sin_e;
    k->u1 = 0.0;
    k->u2 = 0.0;
    k->t_load = t_load;
    k->fric = 0.0;
    k->t_cog = 0.0;
    k->frozen = p->hold_speed;
    k->blocked = -1;
    k->lam = 0.0;
    x->id = p->i_d_a;
    x->iq = p->i_q_a;
    x->w = p->omega_m_rad_s;
    x->th = 0.0;
}

PL_INLINE void advance_on_mm(plant_t *p, int mode, int mm, double u1, double u2, double t_load)
{
    ctx_t k;
    xs_t x;
    double aud = 0.0, auq = 0.0, th_tot = 0.0;
    const double h = p->h_s;
    int n;

    ctx_start(p, &k, &x, t_load);
    k.u1 = u1;
    k.u2 = u2;
    for (n = 0; n < p->cfg.substeps; n++) {
        mech_mode(p, &k, &x, mm);
        if (mode == MODE_UDQ) {
            rk4(p, &k, &x, h, MODE_UDQ, mm, &aud, &auq, &th_tot);
        } else {
            rk4(p, &k, &x, h, MODE_KNOWN, mm, &aud, &auq, &th_tot);
        }
        mech_clamp(&k, &x);
    }
    p->diodes_valid = false;
    p->load_nm = t_load;
    finish_period(p, &k, &x, th_tot, aud, auq);
}

/* one branch per period: the magnetics with effects, or the linear machine */
static void advance_on(plant_t *p, int mode, double u1, double u2, double t_load)
{
    if (p->mag_general) {
        advance_on_mm(p, mode, 1, u1, u2, t_load);
    } else {
        advance_on_mm(p, mode, 0, u1, u2, t_load);
    }
}

/* ------------------------------------------------------------------ PWM off: diode bridge */


/* open phase b: set i_b = 0 exactly by removing the current's component along g = R(-theta_e) e_b;
 * if the remaining pair no longer flows in its diodes' direction, everything is open */
static void block_phase(plant_t *p, const ctx_t *k, xs_t *x, int b)
{
    const double gd = k->c0 * EX[b] + k->s0 * EY[b], gq = -k->s0 * EX[b] + k->c0 * EY[b];
    const double ix = gd * x->id + gq * x->iq;
    double i3[3];
    int n, nblk = 0;
    x->id -= ix * gd;
    x->iq -= ix * gq;
    p->diode[b] = 0;
    phase_currents(k->c0, k->s0, x->id, x->iq, i3);
    for (n = 0; n < 3; n++) {
        if (p->diode[n] == 0 || (double)p->diode[n] * i3[n] <= 0.0) {
            nblk++;
        }
    }
    if (nblk >= 2) {
        x->id = 0.0;
        x->iq = 0.0;
        p->diode[0] = p->diode[1] = p->diode[2] = 0;
    }
}

/* known (stationary-frame) voltage of the conducting diodes; open terminals counted as 0 */
static void diode_voltage(const plant_t *p, double *ual, double *ube)
{
    double v[3];
    int n;
    for (n = 0; n < 3; n++) {
        v[n] = p->diode[n] > 0 ? -p->cfg.v_drop_v : (p->diode[n] < 0 ? p->v_dc_v + p->cfg.v_drop_v : 0.0);
    }
    *ual = (2.0 * v[0] - v[1] - v[2]) * (1.0 / 3.0);
    *ube = (v[1] - v[2]) * PL_INV_SQRT3;
}

static int diode_mode(const plant_t *p, int *blocked)
{
    int n, nb = 0;
    *blocked = -1;
    for (n = 0; n < 3; n++) {
        if (p->diode[n] == 0) {
            nb++;
            *blocked = n;
        }
    }
    return nb == 0 ? MODE_KNOWN : (nb == 1 ? MODE_ONE_BLOCKED : MODE_ALL_BLOCKED);
}

/* an open phase (or pair) starts to conduct when its floating terminal would leave the DC rails */
static void diode_unblock(plant_t *p, ctx_t *k, const xs_t *x)
{
    const base_t b = {k->c0, k->s0, 0.0};
    const double vd = p->cfg.v_drop_v;
    dx_t d;
    double eal, ebe, e3[3];
    int mode = diode_mode(p, &k->blocked), n, hi = 0, lo = 0;
    if (mode == MODE_KNOWN) {
        return;
    }
    diode_voltage(p, &k->u1, &k->u2);
    deriv(p, k, x, &d, mode, p->mag_general ? 1 : 0, &b, 1);
    if (mode == MODE_ONE_BLOCKED) {
        const double vx = 1.5 * k->lam;   /* floating terminal voltage above DC- */
        if (vx > p->v_dc_v + vd) {
            p->diode[k->blocked] = -1;
        } else if (vx < -vd) {
            p->diode[k->blocked] = 1;
        }
        return;
    }
    /* all open: the terminals sit at the phase back-EMFs plus a common float */
    eal = k->c0 * d.ud - k->s0 * d.uq;
    ebe = k->s0 * d.ud + k->c0 * d.uq;
    for (n = 0; n < 3; n++) {
        e3[n] = EX[n] * eal + EY[n] * ebe;
        if (e3[n] > e3[hi]) {
            hi = n;
        }
        if (e3[n] < e3[lo]) {
            lo = n;
        }
    }
    if (e3[hi] - e3[lo] > p->v_dc_v + 2.0 * vd) {
        p->diode[hi] = -1;   /* the highest back-EMF drives current out through the upper diode */
        p->diode[lo] = 1;
    }
}

/* PWM off for one period. Each phase is clamped by a diode to the rail that opposes its current
 * (i > 0: lower diode, terminal at -v_drop; i < 0: upper diode, v_dc + v_drop); a phase whose current
 * reaches zero opens (its terminal floats, its current stays zero); an open phase or pair conducts
 * again only if the back-EMF pushes its terminal beyond a rail (uncontrolled rectification). */
static void advance_off(plant_t *p, double t_load)
{
    ctx_t k;
    xs_t x, x0;
    double aud = 0.0, auq = 0.0, th_tot = 0.0;
    const int mm = p->mag_general ? 1 : 0;
    int n;

    ctx_start(p, &k, &x, t_load);
    if (!p->diodes_valid) {  /* switches just opened: each current keeps flowing through the opposite diode */
        double i3[3];
        int b = -1, nb = 0;
        phase_currents(k.c0, k.s0, x.id, x.iq, i3);
        for (n = 0; n < 3; n++) {
            p->diode[n] = (int8_t)(i3[n] > 1e-9 ? 1 : (i3[n] < -1e-9 ? -1 : 0));
            if (p->diode[n] == 0) {
                nb++;
                b = n;
            }
        }
        if (nb == 1) {
            block_phase(p, &k, &x, b);
        } else if (nb > 1) {
            x.id = x.iq = 0.0;
            p->diode[0] = p->diode[1] = p->diode[2] = 0;
        }
    }

    for (n = 0; n < p->cfg.substeps; n++) {
        double rem = p->h_s;
        int iter;
        for (iter = 0; iter < 8 && rem > 0.0; iter++) {
            const double aud0 = aud, auq0 = auq, th0 = th_tot, c0 = k.c0, s0 = k.s0;
            double frac = 2.0, i0[3], i1[3];
            int mode, y, ev = -1;
            diode_unblock(p, &k, &x);
            mode = diode_mode(p, &k.blocked);
            diode_voltage(p, &k.u1, &k.u2);
            mech_mode(p, &k, &x, mm);
            x0 = x;
            phase_currents(k.c0, k.s0, x.id, x.iq, i0);
            rk4(p, &k, &x, rem, mode, mm, &aud, &auq, &th_tot);
            if (mode != MODE_ALL_BLOCKED && iter < 7) {
                phase_currents(k.c0, k.s0, x.id, x.iq, i1);
                for (y = 0; y < 3; y++) {
                    const double a0 = (double)p->diode[y] * i0[y], a1 = (double)p->diode[y] * i1[y];
                    if (p->diode[y] != 0 && a1 <= 0.0) {
                        const double f = a0 > 0.0 ? a0 / (a0 - a1) : 0.0;
                        if (f < frac) {
                            frac = f;
                            ev = y;
                        }
                    }
                }
            }
            if (ev < 0) {  /* no current zero inside the piece (or the last try): accept it */
                if (mode != MODE_ALL_BLOCKED) {
                    phase_currents(k.c0, k.s0, x.id, x.iq, i1);
                    for (y = 0; y < 3; y++) {
                        if (p->diode[y] != 0 && (double)p->diode[y] * i1[y] <= 0.0) {
                            block_phase(p, &k, &x, y);
                            break;
                        }
                    }
                }
                mech_clamp(&k, &x);
                break;
            }
            /* a conducting current reaches zero inside the piece: redo the piece up to the zero
             * (linear interpolation of the crossing), open that phase, go on with the rest */
            x = x0;
            aud = aud0;
            auq = auq0;
            th_tot = th0;
            k.c0 = c0;
            k.s0 = s0;
            if (frac > 0.0) {
                rk4(p, &k, &x, frac * rem, mode, mm, &aud, &auq, &th_tot);
                mech_clamp(&k, &x);
            }
            block_phase(p, &k, &x, ev);
            rem -= frac * rem;
        }
    }
    p->diodes_valid = true;
    p->load_nm = t_load;
    finish_period(p, &k, &x, th_tot, aud, auq);
}

/* ------------------------------------------------------------------ API */

void plant_cfg_default(plant_cfg_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    cfg->r_s_ohm = 0.9;
    cfg->l_d_h = 5e-3;
    cfg->l_q_h = 12e-3;
    cfg->psi_f_wb = 0.18;
    cfg->pole_pairs = 4;
    cfg->j_kgm2 = 0.0036;
    cfg->b_visc_nms = 0.0;
    cfg->t_coulomb_nm = 0.0;
    cfg->v_dc_v = 540.0;
    cfg->dead_time_s = 0.0;
    cfg->v_drop_v = 0.0;
    cfg->i_dt_a = 0.5;
    cfg->i_noise_a = 0.0;
    cfg->adc_lsb_a = 0.0;
    cfg->enc_counts = 10000u;
    cfg->enc_offset_rad = 0.0;
    cfg->ts_s = 50e-6;
    cfg->substeps = 1;
    cfg->seed = 1u;
    cfg->temp_ambient_c = 25.0;
    /* rig effects, all off; the thermal numbers are those of docs/rigs.md's thermal effect */
    cfg->map = NULL;
    cfg->thermal_on = 0;
    cfg->temp_ref_c = 25.0;
    cfg->temp_winding0_c = 25.0;
    cfg->temp_magnet0_c = 25.0;
    cfg->alpha_r_per_k = 0.00393;
    cfg->alpha_psi_per_k = -0.001;
    cfg->c_winding_j_k = 1500.0;
    cfg->c_magnet_j_k = 600.0;
    cfg->r_wa_k_w = 0.4;
    cfg->r_wm_k_w = 0.5;
    cfg->r_ma_k_w = 1.0;
    cfg->r_fe_heat_ohm = 0.0;
    cfg->psi5_rel = 0.0;
    cfg->psi7_rel = 0.0;
    cfg->cog_nm = 0.0;
    cfg->cog_order_e = 6;
    cfg->cog_phase_rad = 0.0;
    cfg->i_offset_a[0] = cfg->i_offset_a[1] = cfg->i_offset_a[2] = 0.0;
    cfg->i_gain[0] = cfg->i_gain[1] = cfg->i_gain[2] = 1.0;
    cfg->sample_delay_s = 0.0;
    cfg->pwm_delay_periods = 0;
    cfg->dc_on = 0;
    cfg->dc_r_src_ohm = 0.5;
    cfg->dc_c_f = 1e-3;
    cfg->dc_rectifier = 1;
    cfg->dc_grid_hz = 50.0;
    cfg->r_fe_ohm = 0.0;
}

const char *plant_cfg_check(const plant_cfg_t *cfg)
{
    if (!(cfg->r_s_ohm >= 0.0)) return "r_s_ohm must be >= 0";
    if (!(cfg->l_d_h > 0.0)) return "l_d_h must be > 0";
    if (!(cfg->l_q_h > 0.0)) return "l_q_h must be > 0";
    if (!(cfg->psi_f_wb >= 0.0)) return "psi_f_wb must be >= 0";
    if (cfg->pole_pairs < 1) return "pole_pairs must be >= 1";
    if (!(cfg->j_kgm2 > 0.0)) return "j_kgm2 must be > 0";
    if (!(cfg->b_visc_nms >= 0.0)) return "b_visc_nms must be >= 0";
    if (!(cfg->t_coulomb_nm >= 0.0)) return "t_coulomb_nm must be >= 0";
    if (!(cfg->v_dc_v >= 0.0)) return "v_dc_v must be >= 0";
    if (!(cfg->dead_time_s >= 0.0 && cfg->dead_time_s < cfg->ts_s)) return "dead_time_s must be in [0, ts_s)";
    if (!(cfg->v_drop_v >= 0.0)) return "v_drop_v must be >= 0";
    if (!(cfg->i_noise_a >= 0.0)) return "i_noise_a must be >= 0";
    if (!(cfg->adc_lsb_a >= 0.0)) return "adc_lsb_a must be >= 0";
    if (cfg->enc_counts < 1u) return "enc_counts must be >= 1";
    if (!(cfg->ts_s > 0.0)) return "ts_s must be > 0";
    if (cfg->substeps < 1) return "substeps must be >= 1";
    if (cfg->map != NULL && (cfg->map->nd < 2 || cfg->map->nq < 2)) return "map is not built (plant_map_build)";
    if (cfg->thermal_on) {
        if (!(cfg->c_winding_j_k > 0.0) || !(cfg->c_magnet_j_k > 0.0)) return "thermal capacities must be > 0";
        if (!(cfg->r_wa_k_w > 0.0) || !(cfg->r_wm_k_w > 0.0) || !(cfg->r_ma_k_w > 0.0)) return "thermal resistances must be > 0";
        if (!(cfg->ts_s * PLANT_THERMAL_DIV < 0.2 * cfg->c_winding_j_k * cfg->r_wm_k_w) ||
            !(cfg->ts_s * PLANT_THERMAL_DIV < 0.2 * cfg->c_magnet_j_k * cfg->r_wm_k_w) ||
            !(cfg->ts_s * PLANT_THERMAL_DIV < 0.2 * cfg->c_winding_j_k * cfg->r_wa_k_w) ||
            !(cfg->ts_s * PLANT_THERMAL_DIV < 0.2 * cfg->c_magnet_j_k * cfg->r_ma_k_w))
            return "thermal time constants must exceed 5 thermal steps (16 ts_s each)";
    }
    if (!(cfg->r_fe_heat_ohm >= 0.0)) return "r_fe_heat_ohm must be >= 0";
    if (!(fabs(cfg->psi5_rel) < 1.0) || !(fabs(cfg->psi7_rel) < 1.0)) return "flux harmonics must be < 1";
    if (cfg->cog_nm != 0.0 && (cfg->cog_order_e < 1 || cfg->cog_order_e > 1000)) return "cog_order_e must be in [1, 1000]";
    if (!(fabs(cfg->i_gain[0]) < 10.0) || !(fabs(cfg->i_gain[1]) < 10.0) || !(fabs(cfg->i_gain[2]) < 10.0)) return "i_gain must be finite";
    if (!(fabs(cfg->i_offset_a[0]) < 1e6) || !(fabs(cfg->i_offset_a[1]) < 1e6) || !(fabs(cfg->i_offset_a[2]) < 1e6)) return "i_offset_a must be finite";
    if (!(cfg->sample_delay_s >= 0.0 && cfg->sample_delay_s <= (double)(PLANT_DELAY_RING - 3) * cfg->ts_s)) return "sample_delay_s must be in [0, 29 ts_s]";
    if (cfg->pwm_delay_periods < 0 || cfg->pwm_delay_periods > PLANT_DELAY_RING - 1) return "pwm_delay_periods must be in [0, 31]";
    if (cfg->dc_on) {
        if (!(cfg->dc_r_src_ohm > 0.0)) return "dc_r_src_ohm must be > 0";
        if (!(cfg->dc_c_f > 0.0)) return "dc_c_f must be > 0";
        if (!(cfg->dc_grid_hz >= 0.0)) return "dc_grid_hz must be >= 0";
    }
    if (!(cfg->r_fe_ohm >= 0.0)) return "r_fe_ohm must be >= 0";
    return NULL;
}

void plant_init(plant_t *p, const plant_cfg_t *cfg)
{
    memset(p, 0, sizeof *p);
    p->cfg = *cfg;
    if (p->cfg.substeps < 1) {
        p->cfg.substeps = 1;
    }
    if (p->cfg.pole_pairs < 1) {
        p->cfg.pole_pairs = 1;
    }
    if (p->cfg.enc_counts < 1u) {
        p->cfg.enc_counts = 1u;
    }
    p->r_s_ohm = cfg->r_s_ohm;
    p->l_d_h = cfg->l_d_h;
    p->l_q_h = cfg->l_q_h;
    p->psi_f_wb = cfg->psi_f_wb;
    p->v_dc_v = cfg->v_dc_v;
    p->temp_winding_c = cfg->temp_ambient_c;
    p->temp_magnet_c = cfg->temp_ambient_c;
    p->inv_l_d = 1.0 / cfg->l_d_h;
    p->inv_l_q = 1.0 / cfg->l_q_h;
    p->inv_j = 1.0 / cfg->j_kgm2;
    p->inv_i_dt = cfg->i_dt_a > 0.0 ? 1.0 / cfg->i_dt_a : 0.0;
    p->dist_on = p->inv_i_dt > 0.0 && (cfg->v_drop_v > 0.0 || cfg->dead_time_s > 0.0);
    p->inv_lsb = cfg->adc_lsb_a > 0.0 ? 1.0 / cfg->adc_lsb_a : 0.0;
    p->enc_scale = (double)p->cfg.enc_counts / PL_TWO_PI;
    p->enc_off_w = wrap_2pi(fmod(cfg->enc_offset_rad, PL_TWO_PI));
    p->h_s = cfg->ts_s / (double)p->cfg.substeps;
    p->inv_ts = 1.0 / cfg->ts_s;
    p->cos_e = 1.0;
    p->sin_e = 0.0;
    p->pwm_prev = false;
    rng_seed(&p->rng, cfg->seed);
    /* rig effects */
    p->psi_f_ref_wb = cfg->map != NULL ? cfg->map->psi_f_wb : cfg->psi_f_wb;
    p->psi_f_wb = p->psi_f_ref_wb;
    p->psi_shift_wb = 0.0;
    if (cfg->thermal_on) {
        p->temp_winding_c = cfg->temp_winding0_c;
        p->temp_magnet_c = cfg->temp_magnet0_c;
        thermal_params(p);
    }
    p->inv_r_fe = cfg->r_fe_ohm > 0.0 ? 1.0 / cfg->r_fe_ohm : 0.0;
    p->mag_general = cfg->map != NULL || cfg->psi5_rel != 0.0 || cfg->psi7_rel != 0.0 || cfg->cog_nm != 0.0 ||
                     p->inv_r_fe > 0.0;
    p->cog_c = cos(cfg->cog_phase_rad);
    p->cog_s = sin(cfg->cog_phase_rad);
    if (cfg->sample_delay_s > 0.0) {
        const double nd = floor(cfg->sample_delay_s * p->inv_ts + 1e-9);
        p->delay_n = (int)nd;
        p->delay_f = cfg->sample_delay_s * p->inv_ts - nd;
        if (p->delay_f < 0.0) {
            p->delay_f = 0.0;
        }
        hist_fill(p);
    } else {
        p->delay_n = -1;
        p->delay_f = 0.0;
    }
    p->sens_general = p->delay_n >= 0 || cfg->i_offset_a[0] != 0.0 || cfg->i_offset_a[1] != 0.0 ||
                      cfg->i_offset_a[2] != 0.0 || cfg->i_gain[0] != 1.0 || cfg->i_gain[1] != 1.0 ||
                      cfg->i_gain[2] != 1.0;
    p->fifo_pos = 0u;
    p->v_src_v = cfg->v_dc_v;
    p->grid_c = 1.0;
    p->grid_s = 0.0;
    p->grid_dc = cos(PL_TWO_PI * cfg->dc_grid_hz * cfg->ts_s);
    p->grid_ds = sin(PL_TWO_PI * cfg->dc_grid_hz * cfg->ts_s);
    p->i_dc_a = 0.0;
}


/* DC link over the last period: C dv/dt = i_src - i_dc, i_src = (v_s - v)/R_src while the source
 * conducts (a diode rectifier only forwards), v_s the six-pulse rectified grid (line peak = v_src) or
 * a DC source; implicit Euler (R_src C may be a few periods). i_dc from the switch states (or duties)
 * and the mean of the phase currents at the period's start and end; PWM off: the upper diodes of the
 * phases with negative current feed the link. */
static void dc_link_step(plant_t *p, const double d[3], bool pwm_on, const double i0[3])
{
    double i1[3], idc = 0.0, vs = p->v_src_v, vnc;
    const double dt = p->cfg.ts_s, g = 1.0 / p->cfg.dc_r_src_ohm, inv_c = 1.0 / p->cfg.dc_c_f;
    int n;
    phase_currents(p->cos_e, p->sin_e, p->i_d_a, p->i_q_a, i1);
    for (n = 0; n < 3; n++) {
        const double im = 0.5 * (i0[n] + i1[n]);
        idc += pwm_on ? d[n] * im : (im < 0.0 ? im : 0.0);
    }
    p->i_dc_a = idc;
    if (p->cfg.dc_rectifier) {
        double c = p->grid_c * p->grid_dc - p->grid_s * p->grid_ds, s = p->grid_s * p->grid_dc + p->grid_c * p->grid_ds;
        const double r = 1.5 - 0.5 * (c * c + s * s);
        double a0, a1, a2, mx;
        c *= r;
        s *= r;
        p->grid_c = c;
        p->grid_s = s;
        /* the largest of the six line-to-line voltages: max |cos(th - k pi/3)|, k = 0, 1, 2 */
        a0 = fabs(c);
        a1 = fabs(0.5 * c + PL_SQRT3_2 * s);
        a2 = fabs(0.5 * c - PL_SQRT3_2 * s);
        mx = a0 > a1 ? a0 : a1;
        mx = mx > a2 ? mx : a2;
        vs *= mx;
    }
    vnc = p->v_dc_v - dt * inv_c * idc;               /* source not conducting */
    if (p->cfg.dc_rectifier && vnc >= vs) {
        p->v_dc_v = vnc;
    } else {
        const double a = dt * g * inv_c;
        p->v_dc_v = (vnc + a * vs) / (1.0 + a);
    }
    if (p->v_dc_v < 0.0) {
        p->v_dc_v = 0.0;
    }
}

static void step_legs_now(plant_t *p, const double d[3], bool pwm_on, bool carrier, double t_load);

/* the PWM-update delay (whole periods) and the DC link around one period of the inverter */
static void step_legs(plant_t *p, const double d_in[3], bool on_in, bool carrier_in, double t_load)
{
    const double *d = d_in;
    bool pwm_on = on_in, carrier = carrier_in;
    double i0[3];
    if (p->cfg.pwm_delay_periods > 0) {
        const uint32_t w = p->fifo_pos, r = (w - (uint32_t)p->cfg.pwm_delay_periods) & (PLANT_DELAY_RING - 1u);
        p->fifo_d[w][0] = d_in[0];
        p->fifo_d[w][1] = d_in[1];
        p->fifo_d[w][2] = d_in[2];
        p->fifo_on[w] = on_in;
        p->fifo_carrier[w] = carrier_in;
        p->fifo_pos = (w + 1u) & (PLANT_DELAY_RING - 1u);
        d = p->fifo_d[r];
        pwm_on = p->fifo_on[r];
        carrier = p->fifo_carrier[r];
    }
    if (!p->cfg.dc_on) {
        step_legs_now(p, d, pwm_on, carrier, t_load);
        return;
    }
    phase_currents(p->cos_e, p->sin_e, p->i_d_a, p->i_q_a, i0);
    step_legs_now(p, d, pwm_on, carrier, t_load);
    dc_link_step(p, d, pwm_on, i0);
}

/* switching (d = 0 or 1, held over the period, transitions at the period start) or averaged PWM
 * (carrier: 0 < d < 1 means one rising and one falling edge in the period) */
static void step_legs_now(plant_t *p, const double d[3], bool pwm_on, bool carrier, double t_load)
{
    double i3[3], v[3], k_dt_v, was_on;
    int n;
    if (!pwm_on) {
        advance_off(p, t_load);
        p->pwm_prev = false;
        return;
    }
    k_dt_v = p->v_dc_v * p->cfg.dead_time_s / p->cfg.ts_s;
    was_on = p->pwm_prev ? 1.0 : 0.0;
    if (!p->dist_on) {   /* ideal inverter */
        for (n = 0; n < 3; n++) {
            v[n] = p->v_dc_v * d[n];
            p->s_prev[n] = (uint16_t)(d[n] > 0.5);
        }
        advance_on(p, MODE_KNOWN, (2.0 * v[0] - v[1] - v[2]) * (1.0 / 3.0), (v[1] - v[2]) * PL_INV_SQRT3, t_load);
        p->pwm_prev = true;
        return;
    }
    phase_currents(p->cos_e, p->sin_e, p->i_d_a, p->i_q_a, i3);
    for (n = 0; n < 3; n++) {
        double rise, fall;
        if (carrier) {
            rise = fall = (d[n] > 0.0 && d[n] < 1.0) ? 1.0 : 0.0;
        } else {   /* arithmetic, not branches: FCS switch sequences are unpredictable */
            const double sp = (double)p->s_prev[n];
            rise = was_on * d[n] * (1.0 - sp);
            fall = was_on * sp * (1.0 - d[n]);
        }
        p->v_dist_v[n] = leg_dist(p, i3[n], rise, fall, k_dt_v);
        v[n] = p->v_dc_v * d[n] + p->v_dist_v[n];
        p->s_prev[n] = (uint16_t)(d[n] > 0.5);
    }
    advance_on(p, MODE_KNOWN, (2.0 * v[0] - v[1] - v[2]) * (1.0 / 3.0), (v[1] - v[2]) * PL_INV_SQRT3, t_load);
    p->pwm_prev = true;
}

void plant_step(plant_t *p, const fw_cmd_t *cmd)
{
    double d[3];
    d[0] = (double)(cmd->s_a != 0);
    d[1] = (double)(cmd->s_b != 0);
    d[2] = (double)(cmd->s_c != 0);
    step_legs(p, d, cmd->pwm_on, false, (double)cmd->load_nm);
}

void plant_step_duty(plant_t *p, const double duty[3], bool pwm_on, double load_nm)
{
    double d[3];
    int n;
    for (n = 0; n < 3; n++) {
        d[n] = duty[n] < 0.0 ? 0.0 : (duty[n] > 1.0 ? 1.0 : duty[n]);
    }
    step_legs(p, d, pwm_on, true, load_nm);
}

void plant_step_udq(plant_t *p, double u_d_v, double u_q_v, double load_nm)
{
    advance_on(p, MODE_UDQ, u_d_v, u_q_v, load_nm);
    p->pwm_prev = false;   /* not an inverter: no switch history */
}

void plant_set_mech(plant_t *p, double theta_m_rad, double omega_m_rad_s, bool hold_speed)
{
    const double the = (double)p->cfg.pole_pairs * wrap_2pi(fmod(theta_m_rad, PL_TWO_PI));
    p->theta_m_rad = wrap_2pi(fmod(theta_m_rad, PL_TWO_PI));
    p->omega_m_rad_s = omega_m_rad_s;
    p->hold_speed = hold_speed;
    p->cos_e = cos(the);
    p->sin_e = sin(the);
    if (p->delay_n >= 0) {
        hist_fill(p);
    }
}

void plant_set_currents(plant_t *p, double i_d_a, double i_q_a)
{
    p->i_d_a = i_d_a;
    p->i_q_a = i_q_a;
    p->diodes_valid = false;   /* re-derive the diode states from the current signs if PWM is off next */
    if (p->delay_n >= 0) {
        hist_fill(p);
    }
}

void plant_truth(const plant_t *p, plant_truth_t *t)
{
    plant_mag_t m;
    double i3[3], idm, iqm;
    const double pp = (double)p->cfg.pole_pairs;
    mag_at(p, p->mag_general ? 1 : 0, p->i_d_a, p->i_q_a, pp * p->omega_m_rad_s, p->cos_e, p->sin_e, &m, &idm, &iqm);
    phase_currents(p->cos_e, p->sin_e, p->i_d_a, p->i_q_a, i3);
    t->i_d_a = p->i_d_a;
    t->i_q_a = p->i_q_a;
    t->theta_m_rad = p->theta_m_rad;
    t->theta_e_rad = wrap_2pi(fmod(pp * p->theta_m_rad, PL_TWO_PI));
    t->omega_m_rad_s = p->omega_m_rad_s;
    t->speed_rpm = p->omega_m_rad_s * (30.0 / PL_PI);
    t->torque_nm = torque_of(p, idm, iqm, &m) + cog_torque(p, p->cos_e, p->sin_e);
    t->u_d_v = p->u_d_avg_v;
    t->u_q_v = p->u_q_avg_v;
    t->r_s_ohm = p->r_s_ohm;
    t->l_d_h = m.l_dd;   /* incremental inductances in force (the nominal ones for the linear machine) */
    t->l_q_h = m.l_qq;
    t->l_dq_h = m.l_dq;
    t->psi_d_wb = m.psi_d_wb;
    t->psi_q_wb = m.psi_q_wb;
    losses(p, &t->p_cu_w, &t->p_fe_w);
    t->i_dc_a = p->i_dc_a;
    t->v_dist_v[0] = p->v_dist_v[0];
    t->v_dist_v[1] = p->v_dist_v[1];
    t->v_dist_v[2] = p->v_dist_v[2];
    t->psi_f_wb = p->psi_f_wb;
    t->temp_winding_c = p->temp_winding_c;
    t->temp_magnet_c = p->temp_magnet_c;
    t->t_s = (double)p->n_periods * p->cfg.ts_s;
    t->i_a_a = i3[0];
    t->i_b_a = i3[1];
    t->i_c_a = i3[2];
    t->omega_e_rad_s = pp * p->omega_m_rad_s;
    t->v_dc_v = p->v_dc_v;
    t->load_nm = p->load_nm;
}

void plant_set_param_scale(plant_t *p, const plant_cfg_t *base, double r_s_scale, double psi_f_scale)
{
    const double r_new = base->r_s_ohm * r_s_scale;
    const double psi_old_scale = base->psi_f_wb > 0.0 ? p->cfg.psi_f_wb / base->psi_f_wb : 1.0;
    const double k_psi = psi_old_scale > 0.0 ? psi_f_scale / psi_old_scale : 1.0;
    const double psi_before = p->psi_f_wb;
    p->r_s_ohm = p->cfg.r_s_ohm > 0.0 ? p->r_s_ohm * (r_new / p->cfg.r_s_ohm) : r_new;
    p->cfg.r_s_ohm = r_new;
    p->cfg.psi_f_wb = base->psi_f_wb * psi_f_scale;
    p->psi_f_ref_wb *= k_psi;
    p->psi_f_wb *= k_psi;
    p->psi_shift_wb += p->psi_f_wb - psi_before;
}
