/* NLMS-Adaline estimator of L_d, L_q, psi_f (paper A, section 2.2, eq. (15)), C28x-safe.
 * Per window (est_common.h for the regressions and guards):
 *   e_d = y_d - (R i_d + L_q x_lq),            x_lq = -w i_q
 *   L_q += mu_d e_d x_lq / (delta + x_lq^2)
 *   e_q = y_q - (L_d x_ld + psi_f w),          x_ld = w i_d
 *   [L_d psi_f] += mu_q e_q [k x_ld w] / (delta + k x_ld^2 + w^2)   (x_ld centred, below)
 *   R += mu_R g, g = e_d x / (delta_r + x^2)  (online refinement after convergence, along the
 *                                              excitation x = i_d - mean; est_common.h for the
 *                                              slope and its offset at an operating point)
 * mu_R is 0 (R held) until the innovation g, averaged over about 20 windows, leaves four times
 * that average's own noise: a change of R, after which the slope is the mean of the windows' own
 * slopes over the next 160 windows (est_nlms.c).
 * Weights start at zero (paper); R starts nominal until est_nlms_set_r. */
#ifndef EST_NLMS_H
#define EST_NLMS_H

#include "est_common.h"

typedef struct {
    est_core_t core;
    float mu_q; /* variable step of the q regression (Kwong-Johnston: grows with the error power) */
    float g_r;  /* the R innovation averaged over about 20 windows (ohm) */
    float g_r2; /* its mean square per window while R holds (ohm^2), about 64 windows */
    uint16_t r_adapt_n; /* windows since a change of R was detected (0: holding) */
    float k_ld2; /* weight of the L_d input in the q step: (cfg.i_d_exc_ref_a / excitation)^2 */
} est_nlms_t;

void est_nlms_init(est_nlms_t *e, const est_cfg_t *cfg);
void est_nlms_set_r(est_nlms_t *e, float r_s_ohm);
/* The running segment's i_d excitation amplitude, A (0: none): sets k = (i_d_exc_ref_a / it)^2,
 * so that the q step splits between L_d and psi_f as at the tuning amplitude (1 without one). */
void est_nlms_set_excitation(est_nlms_t *e, float inject_a);
void est_nlms_step(est_nlms_t *e, const id_sample_t *s, est_out_t *out);

#endif
