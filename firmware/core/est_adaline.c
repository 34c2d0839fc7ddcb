#include "est_adaline.h"

void est_adaline_init(est_adaline_t *e, const est_cfg_t *cfg)
{
    est_core_init(&e->core, cfg);
}

void est_adaline_set_r(est_adaline_t *e, float r_s_ohm)
{
    est_core_set_r(&e->core, r_s_ohm);
}

void est_adaline_step(est_adaline_t *e, const id_sample_t *s, est_out_t *out)
{
    est_core_t *c = &e->core;
    est_excite_t x;
    float y_d, y_q;
    est_core_excitation(c, s, &x);
    if (x.any) {
        const float eta_d = c->cfg.x_ref_d2 > 0.0f ? c->cfg.mu_d / c->cfg.x_ref_d2 : 0.0f;
        const float eta_q = c->cfg.x_ref_q2 > 0.0f ? c->cfg.mu_q / c->cfg.x_ref_q2 : 0.0f;
        const float eta_r = c->cfg.x_ref_r2 > 0.0f ? c->cfg.mu_r / c->cfg.x_ref_r2 : 0.0f;
        const float x_r = s->i_d_a, x_lq = -s->w_i_q_a_rad_s;
        const float x_ld = s->w_i_d_a_rad_s, x_psi = s->omega_e_rad_s;
        float e_d, e_q;
        est_core_track_inc(c, s);
        est_core_targets(c, s, &y_d, &y_q);
        e_d = y_d - (c->w[EST_R] * x_r + c->w[EST_LQ] * x_lq);
        if (x.lq) {
            c->w[EST_LQ] += eta_d * e_d * x_lq;
        }
        if (x.r) { /* R along the centred i_d (the excitation), as L_d in the q equation */
            c->w[EST_R] += eta_r * e_d * (x_r - c->i_d_mean);
        }
        e_q = y_q - (c->w[EST_LD] * x_ld + c->w[EST_PSI] * x_psi);
        { /* update along the decorrelated inputs (est_common.h): x1 = w (i_d - mean), x2 = w */
            const float xc = est_core_x_ld_centered(c, s);
            const float d_ld = x.ld ? eta_q * e_q * xc : 0.0f;
            c->w[EST_LD] += d_ld;
            c->w[EST_PSI] += eta_q * e_q * x_psi - c->i_d_mean * d_ld;
        }
    }
    est_core_finish(c, &x);
    est_core_out(c, out);
}
