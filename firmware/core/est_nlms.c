#include "est_nlms.h"

#define EST_NLMS_DELTA   1.0f  /* regularisation, (V/H)^2: negligible against w^2 >= 1600 */
#define EST_NLMS_DELTA_R 0.01f /* A^2 */

/* Variable step of the q regression (L_d, psi_f), after Kwong and Johnston:
 *   mu(k+1) = clamp(alpha mu(k) + gamma e_q(k)^2, mu_min, mu_max)
 * A large error (start from zero weights, a parameter step) drives the step to mu_max for fast
 * convergence; at the noise floor of the window equations (about 0.2 V rms on e_q) it settles
 * near 2 mu_min, which keeps the L_d estimate quiet. mu_max and mu_min scale with cfg.mu_q. */
#define EST_NLMS_VSS_ALPHA    0.95f
#define EST_NLMS_VSS_MAX      4.0f  /* x cfg.mu_q */
#define EST_NLMS_VSS_MIN      0.05f /* x cfg.mu_q */
#define EST_NLMS_VSS_NOISE_V2 0.04f /* e_q^2 at the noise floor, V^2 */

void est_nlms_init(est_nlms_t *e, const est_cfg_t *cfg)
{
    est_core_init(&e->core, cfg);
    e->mu_q = EST_NLMS_VSS_MAX * cfg->mu_q;
}

static float vss_step(est_nlms_t *e, float err_v)
{
    const float mu_max = EST_NLMS_VSS_MAX * e->core.cfg.mu_q;
    const float mu_min = EST_NLMS_VSS_MIN * e->core.cfg.mu_q;
    /* gamma puts the noise-floor equilibrium at 2 mu_min */
    const float gamma = 2.0f * mu_min * (1.0f - EST_NLMS_VSS_ALPHA) / EST_NLMS_VSS_NOISE_V2;
    float mu = EST_NLMS_VSS_ALPHA * e->mu_q + gamma * err_v * err_v;
    if (mu > mu_max) {
        mu = mu_max;
    }
    if (mu < mu_min) {
        mu = mu_min;
    }
    e->mu_q = mu;
    return mu;
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
        if (x.r) { /* R along the centred i_d (the excitation), as L_d in the q equation */
            const float xr = x_r - c->i_d_mean;
            c->w[EST_R] += c->cfg.mu_r * e_d * xr / (EST_NLMS_DELTA_R + xr * xr);
        }
        e_q = y_q - (c->w[EST_LD] * s->w_i_d_a_rad_s + c->w[EST_PSI] * x_psi);
        { /* update along the decorrelated inputs (est_common.h): x1 = w (i_d - mean), x2 = w */
            const float xc = est_core_x_ld_centered(c, s);
            const float x1 = x.ld ? xc : 0.0f;
            float d_ld, d_th;
            const float mu = vss_step(e, e_q);
            n2 = EST_NLMS_DELTA + x1 * x1 + x_psi * x_psi;
            d_ld = mu * e_q * x1 / n2;
            d_th = mu * e_q * x_psi / n2;
            c->w[EST_LD] += d_ld;
            c->w[EST_PSI] += d_th - c->i_d_mean * d_ld;
        }
        (void)x_ld;
    }
    est_core_finish(c, &x);
    est_core_out(c, out);
}
