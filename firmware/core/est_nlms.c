#include "est_nlms.h"

#define EST_NLMS_DELTA 1.0f      /* regularisation, (V/H)^2: negligible against w^2 >= 1600 */
#define EST_NLMS_DELTA_R 0.01f   /* A^2 */

void est_nlms_init(est_nlms_t *e, const est_cfg_t *cfg)
{
    est_core_init(&e->core, cfg);
}

void est_nlms_set_r(est_nlms_t *e, float r_s_ohm)
{
    est_core_set_r(&e->core, r_s_ohm);
}

void est_nlms_step(est_nlms_t *e, const id_sample_t *s, est_out_t *out)
{
    est_core_t *c = &e->core;
    est_excite_t x;
    float y_d, y_q;
    est_core_excitation(c, s, &x);
    if (x.any) {
        const float x_r = s->i_d_a, x_lq = -s->w_i_q_a_rad_s;
        const float x_ld = x.ld ? s->w_i_d_a_rad_s : 0.0f, x_psi = s->omega_e_rad_s;
        float e_d, e_q, n2;
        est_core_targets(c, s, &y_d, &y_q);
        e_d = y_d - (c->w[EST_R] * x_r + c->w[EST_LQ] * x_lq);
        if (x.lq) {
            c->w[EST_LQ] += c->cfg.mu_d * e_d * x_lq / (EST_NLMS_DELTA + x_lq * x_lq);
        }
        if (x.r) {   /* R along the centred i_d (the excitation), as L_d in the q equation */
            const float xr = x_r - c->i_d_mean;
            c->w[EST_R] += c->cfg.mu_r * e_d * xr / (EST_NLMS_DELTA_R + xr * xr);
        }
        e_q = y_q - (c->w[EST_LD] * s->w_i_d_a_rad_s + c->w[EST_PSI] * x_psi);
        {   /* update along the decorrelated inputs (est_common.h): x1 = w (i_d - mean), x2 = w */
            const float xc = est_core_x_ld_centered(c, s);
            const float x1 = x.ld ? xc : 0.0f;
            float d_ld, d_th;
            n2 = EST_NLMS_DELTA + x1 * x1 + x_psi * x_psi;
            d_ld = c->cfg.mu_q * e_q * x1 / n2;
            d_th = c->cfg.mu_q * e_q * x_psi / n2;
            c->w[EST_LD] += d_ld;
            c->w[EST_PSI] += d_th - c->i_d_mean * d_ld;
        }
        (void)x_ld;
    }
    est_core_finish(c, &x);
    est_core_out(c, out);
}
