#include "est_common.h"

#include <math.h>

#define EST_SLOW_ALPHA 0.03125f /* slow average over about 32 windows */

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
    c->conv_tol = 0.01f;
    c->conv_min_updates = 50u;
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
}

void est_core_targets(const est_core_t *e, const id_sample_t *s, float *y_d, float *y_q)
{
    *y_d = s->u_d_v - e->w[EST_LD] * s->di_d_a_s;
    *y_q = s->u_q_v - e->w[EST_LQ] * s->di_q_a_s - e->w[EST_R] * s->i_q_a;
}

void est_core_finish(est_core_t *e, const est_excite_t *x)
{
    uint16_t i;
    bool settled = true;
    for (i = 0u; i < EST_N; i++) {
        /* the online R stays within [1/2, 2] x the standstill injection's (a winding from 25 to
         * 280 degC changes R by 2x): it comes from the d equation at speed, where an error of the
         * firmware's dead-time model correlates with the i_d excitation */
        const float lo = i == EST_R ? 0.5f * e->r_ref : e->cfg.bound_lo * e->cfg.nominal[i];
        const float hi = i == EST_R ? 2.0f * e->r_ref : e->cfg.bound_hi * e->cfg.nominal[i];
        if (!(e->w[i] >= lo)) { /* also catches NaN */
            e->w[i] = lo;
        } else if (e->w[i] > hi) {
            e->w[i] = hi;
        }
    }
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
    out->r_s_ohm = e->w[EST_R];
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
