#include "est_nlms.h"

#include <math.h>

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

/* The online R's step after its offset is calibrated (est_common.h): at one operating point the
 * d equation's slope tells R only through its changes, and on a saturating rig one window's slope
 * is noisy (lab-typical: 0.3 V per window over +-1.9 A of excitation, 0.18 ohm, 15 % of R). The
 * slope is therefore held until its innovation g, averaged over 1 / (1 - VSS_R_BETA) windows,
 * leaves VSS_R_SIGMA times that average's own noise (the running mean square of g while holding,
 * over about 64 windows; at least VSS_R_FLOOR x R): a change. It then adapts for VSS_R_N windows
 * with the step 1 / (n + VSS_R_N0) at the n-th window (the mean of the windows' slopes since the
 * change was seen), and holds again. While the offset is calibrated the step is mu_r. (Following
 * the change for 40 windows at 2 mu_r before averaging, to forget the step's transient, did worse
 * on the tuning seeds: the drift moves i_q by 5 % and with it the slope's offset.) */
#define EST_NLMS_VSS_R_BETA  0.95f
#define EST_NLMS_VSS_R_SIGMA 4.0f
#define EST_NLMS_VSS_R_FLOOR 0.01f /* x R */
#define EST_NLMS_VSS_R_G2A   0.015625f
#define EST_NLMS_VSS_R_N     160u
#define EST_NLMS_VSS_R_N0    2.0f

void est_nlms_init(est_nlms_t *e, const est_cfg_t *cfg)
{
    est_core_init(&e->core, cfg);
    e->mu_q = EST_NLMS_VSS_MAX * cfg->mu_q;
    e->g_r = 0.0f;
    e->g_r2 = 0.0f;
    e->r_adapt_n = 0u;
    e->k_ld2 = 1.0f;
}

void est_nlms_set_excitation(est_nlms_t *e, float inject_a)
{
    const float a = fabsf(inject_a);
    e->k_ld2 = 1.0f;
    if (a > 0.0f && e->core.cfg.i_d_exc_ref_a > 0.0f) {
        const float k = e->core.cfg.i_d_exc_ref_a / a;
        e->k_ld2 = k * k;
    }
}

static float vss_r_step(est_nlms_t *e, float g)
{
    /* the noise of the averaged innovation: sqrt((1 - beta) / (1 + beta)) x that of one window */
    const float k_avg = (1.0f - EST_NLMS_VSS_R_BETA) / (1.0f + EST_NLMS_VSS_R_BETA);
    const float floor = EST_NLMS_VSS_R_FLOOR * e->core.r_ref;
    float g0;
    e->g_r = EST_NLMS_VSS_R_BETA * e->g_r + (1.0f - EST_NLMS_VSS_R_BETA) * g;
    if (e->core.r_state != EST_R_TRACK) {
        e->g_r2 += EST_NLMS_VSS_R_G2A * (g * g - e->g_r2);
        e->r_adapt_n = 0u;
        return e->core.cfg.mu_r;
    }
    if (e->r_adapt_n > 0u) { /* adapting to a change: the mean slope since it was seen */
        const float mu = 1.0f / ((float)e->r_adapt_n + EST_NLMS_VSS_R_N0);
        if (++e->r_adapt_n > EST_NLMS_VSS_R_N) {
            e->r_adapt_n = 0u;
            e->g_r = 0.0f;
        }
        return mu;
    }
    g0 = EST_NLMS_VSS_R_SIGMA * sqrtf(k_avg * e->g_r2);
    if (!(g0 >= floor)) { /* also NaN */
        g0 = floor;
    }
    if (fabsf(e->g_r) > g0) {
        e->r_adapt_n = 1u;
        return 1.0f / EST_NLMS_VSS_R_N0;
    }
    e->g_r2 += EST_NLMS_VSS_R_G2A * (g * g - e->g_r2);
    return 0.0f;
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
        est_core_track_inc(c, s);
        est_core_targets(c, s, &y_d, &y_q);
        e_d = y_d - (c->w[EST_R] * x_r + c->w[EST_LQ] * x_lq);
        if (x.lq) {
            c->w[EST_LQ] += c->cfg.mu_d * e_d * x_lq / (EST_NLMS_DELTA + x_lq * x_lq);
        }
        if (x.r) { /* R along the centred i_d (the excitation), as L_d in the q equation */
            const float xr = x_r - c->i_d_mean;
            const float g = e_d * xr / (EST_NLMS_DELTA_R + xr * xr);
            c->w[EST_R] += vss_r_step(e, g) * g;
        }
        e_q = y_q - (c->w[EST_LD] * s->w_i_d_a_rad_s + c->w[EST_PSI] * x_psi);
        /* update along the decorrelated inputs (est_common.h): x1 = w (i_d - mean), x2 = w, with
         * x1 weighted by k_ld2 = (i_d_exc_ref_a / inject_a)^2 in the norm and the L_d step (a
         * diagonal preconditioner; 1 at the tuning amplitude, paper (15)): x1^2 grows with the
         * excitation's amplitude squared in A^2 against w^2, so without it psi_f's share of the
         * step was 1 / (1 + 16) at +-4 A against 1 / (1 + 4) at +-2 A */
        {
            const float xc = est_core_x_ld_centered(c, s);
            const float x1 = x.ld ? xc : 0.0f;
            float d_ld, d_th;
            const float mu = vss_step(e, e_q);
            n2 = EST_NLMS_DELTA + e->k_ld2 * x1 * x1 + x_psi * x_psi;
            d_ld = mu * e_q * e->k_ld2 * x1 / n2;
            d_th = mu * e_q * x_psi / n2;
            c->w[EST_LD] += d_ld;
            c->w[EST_PSI] += d_th - c->i_d_mean * d_ld;
        }
        (void)x_ld;
    }
    est_core_finish(c, &x);
    est_core_out(c, out);
}
