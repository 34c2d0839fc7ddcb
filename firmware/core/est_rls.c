#include "est_rls.h"

#include <math.h>

#define EST_RLS_P_R     1.0e-2f /* per-unit variance of R after the injection */
#define EST_RLS_P_R_CAL 1.0f    /* ... of the d equation's slope at a new operating point */

static void p_reset(float p[4], float p0)
{
    p[0] = p0;
    p[1] = 0.0f;
    p[2] = 0.0f;
    p[3] = p0;
}

void est_rls_init(est_rls_t *e, const est_cfg_t *cfg)
{
    est_core_init(&e->core, cfg);
    if (!(e->core.cfg.lambda > 0.5f && e->core.cfg.lambda <= 1.0f)) {
        e->core.cfg.lambda = 0.995f;
    }
    if (!(e->core.cfg.p0 > 0.0f)) {
        e->core.cfg.p0 = 100.0f;
    }
    p_reset(e->p_d, e->core.cfg.p0);
    p_reset(e->p_q, e->core.cfg.p0);
}

void est_rls_set_r(est_rls_t *e, float r_s_ohm)
{
    est_core_set_r(&e->core, r_s_ohm);
    e->p_d[0] = EST_RLS_P_R; /* R is known to a few per cent from the injection */
    e->p_d[1] = 0.0f;
    e->p_d[2] = 0.0f;
}

/* One RLS update of th (2, per-unit) with regressor phi and a priori error err; use[i] false leaves
 * parameter i out. */
static void rls2(float p[4], float th[2], const float phi_in[2], const bool use[2], float err,
                 float lambda, float p0)
{
    float phi[2], pp[2], den, k[2];
    uint16_t i;
    if (!use[0] && !use[1]) {
        return;
    }
    phi[0] = use[0] ? phi_in[0] : 0.0f;
    phi[1] = use[1] ? phi_in[1] : 0.0f;
    if (!use[0] || !use[1]) { /* decouple the frozen direction */
        p[1] = 0.0f;
        p[2] = 0.0f;
    }
    pp[0] = p[0] * phi[0] + p[1] * phi[1];
    pp[1] = p[2] * phi[0] + p[3] * phi[1];
    den = lambda + phi[0] * pp[0] + phi[1] * pp[1];
    if (!(den > 1e-12f)) {
        return;
    }
    k[0] = pp[0] / den;
    k[1] = pp[1] / den;
    th[0] += k[0] * err;
    th[1] += k[1] * err;
    for (i = 0u; i < 2u; i++) {
        if (use[i]) {
            const uint16_t r = (uint16_t)(2u * i);
            p[r] = (p[r] - k[i] * pp[0]) / lambda;
            p[r + 1u] = (p[r + 1u] - k[i] * pp[1]) / lambda;
        }
    }
    p[1] = p[2] = 0.5f * (p[1] + p[2]);
    for (i = 0u; i < 2u; i++) { /* cap the diagonal (no wind-up), keep P positive semidefinite */
        const uint16_t d = (uint16_t)(3u * i);
        if (!(p[d] <= p0)) {
            const float sc = sqrtf(p0 / p[d]);
            p[d] = p0;
            p[1] *= sc;
            p[2] *= sc;
        }
        if (!(p[d] > 0.0f)) {
            p[d] = 1e-9f;
        }
    }
}

void est_rls_step(est_rls_t *e, const id_sample_t *s, est_out_t *out)
{
    est_core_t *c = &e->core;
    const float *nom = c->cfg.nominal;
    est_excite_t x;
    float y_d, y_q;
    est_core_excitation(c, s, &x);
    if (x.any && nom[EST_R] > 0.0f && nom[EST_LD] > 0.0f && nom[EST_LQ] > 0.0f &&
        nom[EST_PSI] > 0.0f) {
        float th[2], phi[2], err;
        bool use[2];
        est_core_track_inc(c, s);
        est_core_targets(c, s, &y_d, &y_q);
        if (c->r_cal_new) { /* the slope has to move to its value at this operating point */
            e->p_d[0] = EST_RLS_P_R_CAL;
            e->p_d[1] = 0.0f;
            e->p_d[2] = 0.0f;
            c->r_cal_new = false;
        }
        /* d axis: [R, L_q] */
        th[0] = c->w[EST_R] / nom[EST_R];
        th[1] = c->w[EST_LQ] / nom[EST_LQ];
        phi[0] = s->i_d_a * nom[EST_R];
        phi[1] = -s->w_i_q_a_rad_s * nom[EST_LQ];
        use[0] = x.r;
        use[1] = x.lq;
        err = y_d - (phi[0] * th[0] + phi[1] * th[1]);
        rls2(e->p_d, th, phi, use, err, c->cfg.lambda, c->cfg.p0);
        c->w[EST_R] = th[0] * nom[EST_R];
        c->w[EST_LQ] = th[1] * nom[EST_LQ];
        /* q axis: [L_d, psi_f] */
        th[0] = c->w[EST_LD] / nom[EST_LD];
        th[1] = c->w[EST_PSI] / nom[EST_PSI];
        phi[0] = s->w_i_d_a_rad_s * nom[EST_LD];
        phi[1] = s->omega_e_rad_s * nom[EST_PSI];
        use[0] = x.ld;
        use[1] = x.psi;
        err = y_q - (phi[0] * th[0] + phi[1] * th[1]);
        rls2(e->p_q, th, phi, use, err, c->cfg.lambda, c->cfg.p0);
        c->w[EST_LD] = th[0] * nom[EST_LD];
        c->w[EST_PSI] = th[1] * nom[EST_PSI];
        (void)est_core_x_ld_centered(c, s); /* the i_d mean of the online R's offset */
    }
    est_core_finish(c, &x);
    est_core_out(c, out);
}
