#include "est_common.h"

#include <math.h>

#define EST_SLOW_ALPHA 0.03125f /* slow average over about 32 windows */

/* Incremental inductances of the L di/dt terms: RLS on the window residuals along di/dt, which
 * the FCS ripple excites in every window (hundreds of A/s) and which is uncorrelated with the
 * slow regressors; on a saturating machine they differ between the excitation's levels, hence the
 * terms in x di/dt (x: the window's i_d about its running mean). Both equations share the
 * regressor and so one covariance. Forgetting factor (memory about 200 windows), initial
 * covariance (A/s)^-2 (the gain is full at 100 A/s of ripple), bounds x the motor file's
 * inductances. */
#define EST_INC_LAMBDA 0.995f
#define EST_INC_P0     1.0e-4f
#define EST_INC_LO     0.2f
#define EST_INC_HI     3.0f
#define EST_INC_X_HI   0.5f /* cross terms, x the nominal L_q; slopes in x, the same per ampere */

/* The online R's calibration at an operating point: EST_R_CAL_N windows with R held (about
 * 8 time constants of the R step mu_r 0.04: the slope settles with the other estimates), r_off
 * the slope's mean over its last EST_R_CAL_AVG windows less R (and the slope set to that mean).
 * A new calibration when the speed stays away by more than EST_R_OP_W or i_q by more than
 * EST_R_OP_IQ (relative, at least EST_R_OP_IQ_MIN_A) for EST_R_OP_AWAY_N windows: a new
 * operating point, not the transient of a parameter step (a drift of R and psi_f moves i_q for a
 * while, and a calibration then would take the change of R for the operating point's). */
#define EST_R_CAL_N       200u
#define EST_R_CAL_AVG     80u
#define EST_R_OP_W        0.1f
#define EST_R_OP_IQ       0.2f
#define EST_R_OP_IQ_MIN_A 1.0f
#define EST_R_OP_AWAY_N   64u /* ... for this many windows in a row (not a transient) */

void est_cfg_default(est_cfg_t *c, float r_s_ohm, float l_d_h, float l_q_h, float psi_f_wb,
                     uint16_t pole_pairs)
{
    const float w_ref = 1000.0f * 0.104719755f * (float)pole_pairs; /* 1000 r/min, electrical */
    const float i_q_ref = 5.0f, i_d_ref = 2.0f;
    c->nominal[EST_R] = r_s_ohm;
    c->nominal[EST_LD] = l_d_h;
    c->nominal[EST_LQ] = l_q_h;
    c->nominal[EST_PSI] = psi_f_wb;
    c->bound_lo = 0.0f;
    c->bound_hi = 3.0f;
    c->omega_min_rad_s = 40.0f;
    c->i_d_min_a = 1.0f;
    c->i_q_min_a = 0.5f;
    c->mu_d = 0.1f;
    c->mu_q = 0.1f;
    c->mu_r = 0.04f; /* online R (drift): time constant about 40 windows */
    c->lambda = 0.98f;
    c->p0 = 100.0f;
    c->x_ref_d2 = i_d_ref * i_d_ref + w_ref * w_ref * i_q_ref * i_q_ref;
    c->x_ref_q2 = w_ref * w_ref * (1.0f + i_d_ref * i_d_ref);
    c->x_ref_r2 = i_d_ref * i_d_ref;
    c->i_d_exc_ref_a = i_d_ref;
    c->conv_tol = 0.01f;
    c->conv_min_updates = 50u;
}

static void inc_reset(est_core_t *e)
{
    uint16_t i, j;
    const float p0 = EST_INC_P0;
    for (i = 0u; i < EST_INC_N; i++) {
        e->l_d[i] = 0.0f;
        e->l_q[i] = 0.0f;
        for (j = 0u; j < EST_INC_N; j++) {
            e->p_inc[i][j] = i == j ? p0 : 0.0f;
        }
    }
    e->l_d[0] = e->cfg.nominal[EST_LD];
    e->l_q[1] = e->cfg.nominal[EST_LQ];
}

void est_core_init(est_core_t *e, const est_cfg_t *cfg)
{
    uint16_t i;
    e->cfg = *cfg;
    for (i = 0u; i < EST_N; i++) {
        e->w[i] = 0.0f;
        e->slow[i] = 0.0f;
    }
    e->w[EST_R] = cfg->nominal[EST_R];
    e->r_ref = cfg->nominal[EST_R];
    inc_reset(e);
    e->r_off = 0.0f;
    e->r_hold = cfg->nominal[EST_R];
    e->r_off_sum = 0.0f;
    e->op_w_rad_s = 0.0f;
    e->op_i_q_a = 0.0f;
    e->w_f_rad_s = 0.0f;
    e->i_q_f_a = 0.0f;
    e->r_cal_n = 0u;
    e->op_away_n = 0u;
    e->r_state = EST_R_IDLE;
    e->slow[EST_R] = e->w[EST_R];
    e->updates = 0u;
    e->i_d_mean = 0.0f;
    e->i_d_mean_set = false;
    e->excited = false;
    e->converged = false;
    e->ever_converged = false;
}

void est_core_set_r(est_core_t *e, float r_s_ohm)
{
    const float hi = e->cfg.bound_hi * e->cfg.nominal[EST_R];
    if (r_s_ohm > 0.0f && r_s_ohm <= hi) {
        e->w[EST_R] = r_s_ohm;
        e->slow[EST_R] = r_s_ohm;
        e->r_ref = r_s_ohm;
        e->r_off = 0.0f;
        e->r_state = EST_R_IDLE;
    }
}

void est_core_excitation(const est_core_t *e, const id_sample_t *s, est_excite_t *x)
{
    const est_cfg_t *c = &e->cfg;
    x->any = fabsf(s->omega_e_rad_s) >= c->omega_min_rad_s;
    x->psi = x->any;
    x->ld = x->any && fabsf(s->i_d_a) >= c->i_d_min_a;
    x->lq = x->any && fabsf(s->i_q_a) >= c->i_q_min_a;
    x->r = x->ld && e->ever_converged && c->mu_r > 0.0f;
    x->omega_e_rad_s = s->omega_e_rad_s;
    x->i_q_a = s->i_q_a;
}

static float clampf(float v, float lo, float hi)
{
    if (!(v >= lo)) { /* also catches NaN */
        return lo;
    }
    return v > hi ? hi : v;
}

float est_core_r(const est_core_t *e)
{
    return clampf(e->w[EST_R] - e->r_off, 0.5f * e->r_ref, 2.0f * e->r_ref);
}

/* The regressor of the L di/dt terms */
static void inc_phi(const est_core_t *e, const id_sample_t *s, float phi[EST_INC_N])
{
    const float x = e->i_d_mean_set ? s->i_d_a - e->i_d_mean : 0.0f;
    phi[0] = s->di_d_a_s;
    phi[1] = s->di_q_a_s;
    phi[2] = x * s->di_d_a_s;
    phi[3] = x * s->di_q_a_s;
}

static float dot4(const float a[EST_INC_N], const float b[EST_INC_N])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
}

void est_core_targets(const est_core_t *e, const id_sample_t *s, float *y_d, float *y_q)
{
    float phi[EST_INC_N];
    inc_phi(e, s, phi);
    *y_d = s->u_d_v - dot4(e->l_d, phi) + e->r_off * e->i_d_mean;
    *y_q = s->u_q_v - dot4(e->l_q, phi) - est_core_r(e) * s->i_q_a;
}

void est_core_track_inc(est_core_t *e, const id_sample_t *s)
{
    float y_d, y_q, e_d, e_q, phi[EST_INC_N], pp[EST_INC_N], den;
    uint16_t i, j;
    bool wound = false;
    const float l_d = e->cfg.nominal[EST_LD], l_q = e->cfg.nominal[EST_LQ];
    const float p_max = EST_INC_P0;
    if (!e->ever_converged && e->updates < EST_INC_WARM_N) {
        return; /* the first windows' errors are the parameters' own (tens of volts) */
    }
    est_core_targets(e, s, &y_d, &y_q);
    e_d = y_d - (e->w[EST_R] * s->i_d_a - e->w[EST_LQ] * s->w_i_q_a_rad_s);
    e_q = y_q - (e->w[EST_LD] * s->w_i_d_a_rad_s + e->w[EST_PSI] * s->omega_e_rad_s);
    inc_phi(e, s, phi);
    for (i = 0u; i < EST_INC_N; i++) {
        pp[i] = dot4(e->p_inc[i], phi);
    }
    den = EST_INC_LAMBDA + dot4(phi, pp);
    if (!(den > 0.0f)) {
        return;
    }
    for (i = 0u; i < EST_INC_N; i++) {
        const float k = pp[i] / den;
        e->l_d[i] += k * e_d;
        e->l_q[i] += k * e_q;
    }
    for (i = 0u; i < EST_INC_N; i++) {
        for (j = i; j < EST_INC_N; j++) {
            const float v = (e->p_inc[i][j] - pp[i] * pp[j] / den) / EST_INC_LAMBDA;
            e->p_inc[i][j] = v;
            e->p_inc[j][i] = v;
        }
        if (!(e->p_inc[i][i] <= p_max)) { /* wind-up without ripple, or NaN */
            wound = true;
        }
    }
    if (wound) { /* a fresh covariance, the estimates kept */
        const float p0 = EST_INC_P0;
        for (i = 0u; i < EST_INC_N; i++) {
            for (j = 0u; j < EST_INC_N; j++) {
                e->p_inc[i][j] = i == j ? p0 : 0.0f;
            }
        }
    }
    e->l_d[0] = clampf(e->l_d[0], EST_INC_LO * l_d, EST_INC_HI * l_d);
    e->l_q[1] = clampf(e->l_q[1], EST_INC_LO * l_q, EST_INC_HI * l_q);
    e->l_d[1] = clampf(e->l_d[1], -EST_INC_X_HI * l_q, EST_INC_X_HI * l_q);
    e->l_q[0] = clampf(e->l_q[0], -EST_INC_X_HI * l_q, EST_INC_X_HI * l_q);
    for (i = 2u; i < EST_INC_N; i++) {
        e->l_d[i] = clampf(e->l_d[i], -EST_INC_X_HI * l_q, EST_INC_X_HI * l_q);
        e->l_q[i] = clampf(e->l_q[i], -EST_INC_X_HI * l_q, EST_INC_X_HI * l_q);
    }
}

/* The operating point over about 32 windows (the i_d excitation moves i_q through MTPA's
 * reluctance torque by up to +-1 A within a period) has left the calibration's. */
static bool op_moved(const est_core_t *e)
{
    const float dw = fabsf(e->w_f_rad_s - e->op_w_rad_s);
    const float iq_tol = fmaxf(EST_R_OP_IQ * fabsf(e->op_i_q_a), EST_R_OP_IQ_MIN_A);
    return dw > EST_R_OP_W * fabsf(e->op_w_rad_s) || fabsf(e->i_q_f_a - e->op_i_q_a) > iq_tol;
}

/* The online R's state (est_common.h): calibrate r_off at a new operating point with R held,
 * then let R follow the slope. */
static void r_offset(est_core_t *e, const est_excite_t *x)
{
    if (!x->any) {
        return;
    }
    if (e->r_state == EST_R_IDLE) { /* start the filters at this window */
        e->w_f_rad_s = x->omega_e_rad_s;
        e->i_q_f_a = x->i_q_a;
    }
    e->w_f_rad_s += EST_SLOW_ALPHA * (x->omega_e_rad_s - e->w_f_rad_s);
    e->i_q_f_a += EST_SLOW_ALPHA * (x->i_q_a - e->i_q_f_a);
    if (!x->r) {
        return;
    }
    if (e->r_state == EST_R_TRACK && op_moved(e)) {
        if (e->op_away_n < EST_R_OP_AWAY_N) {
            e->op_away_n++;
        }
    } else {
        e->op_away_n = 0u;
    }
    if (e->r_state == EST_R_IDLE || e->op_away_n >= EST_R_OP_AWAY_N) {
        /* R as it was before this window: the first window with x->r has already moved the
         * slope (w[EST_R]) by one update, which would otherwise become the held R */
        e->r_hold = e->r_state == EST_R_IDLE ? e->r_ref : est_core_r(e);
        e->op_away_n = 0u;
        e->op_w_rad_s = e->w_f_rad_s;
        e->op_i_q_a = e->i_q_f_a;
        e->r_cal_n = 0u;
        e->r_off_sum = 0.0f;
        e->r_state = EST_R_CAL;
        e->r_cal_new = true;
    }
    if (e->r_state == EST_R_CAL) {
        e->r_off = e->w[EST_R] - e->r_hold;
        e->r_cal_n++;
        if (e->r_cal_n > EST_R_CAL_N - EST_R_CAL_AVG) {
            e->r_off_sum += e->r_off;
        }
        if (e->r_cal_n >= EST_R_CAL_N) {
            e->r_off = e->r_off_sum / (float)EST_R_CAL_AVG;
            e->w[EST_R] = e->r_hold + e->r_off; /* the slope at its mean: R = r_hold */
            e->r_state = EST_R_TRACK;
        }
    }
}

void est_core_finish(est_core_t *e, const est_excite_t *x)
{
    uint16_t i;
    bool settled = true;
    for (i = 0u; i < EST_N; i++) {
        /* the d equation's slope (w[EST_R]) stays within [0, 3] x the standstill injection's R;
         * the R reported, within [1/2, 2] x (est_core_r: a winding from 25 to 280 degC changes R
         * by 2x) */
        const float lo = i == EST_R ? 0.0f : e->cfg.bound_lo * e->cfg.nominal[i];
        const float hi = i == EST_R ? 3.0f * e->r_ref : e->cfg.bound_hi * e->cfg.nominal[i];
        if (!(e->w[i] >= lo)) { /* also catches NaN */
            e->w[i] = lo;
        } else if (e->w[i] > hi) {
            e->w[i] = hi;
        }
    }
    r_offset(e, x);
    e->excited = x->ld && x->lq && x->psi;
    if (!x->any) {
        return;
    }
    e->updates++;
    for (i = 0u; i < EST_N; i++) {
        e->slow[i] += EST_SLOW_ALPHA * (e->w[i] - e->slow[i]);
        if (i != EST_R && !(fabsf(e->w[i] - e->slow[i]) <= e->cfg.conv_tol * fabsf(e->slow[i]))) {
            settled = false;
        }
    }
    e->converged = settled && e->updates >= (uint32_t)e->cfg.conv_min_updates;
    if (e->converged) {
        e->ever_converged = true;
    }
}

void est_core_out(const est_core_t *e, est_out_t *out)
{
    out->r_s_ohm = est_core_r(e);
    out->l_d_h = e->w[EST_LD];
    out->l_q_h = e->w[EST_LQ];
    out->psi_f_wb = e->w[EST_PSI];
    out->excited = e->excited;
    out->converged = e->converged;
    out->updates = e->updates;
}

/* 1/128 windows: about one 10 Hz excitation period and a bit */
#define EST_ID_MEAN_ALPHA 0.0078125f

float est_core_x_ld_centered(est_core_t *e, const id_sample_t *s)
{
    const float w = s->omega_e_rad_s;
    if (!e->i_d_mean_set) {
        e->i_d_mean = s->i_d_a;
        e->i_d_mean_set = true;
    } else {
        e->i_d_mean += EST_ID_MEAN_ALPHA * (s->i_d_a - e->i_d_mean);
    }
    return s->w_i_d_a_rad_s - w * e->i_d_mean;
}
