/* Adaline (LMS) estimator of L_d, L_q, psi_f (paper A, section 2.1, eq. (9)), C28x-safe.
 * The same regressions as NLMS (est_common.h), with fixed steps W += 2 eta x e:
 *   2 eta_d = mu_d / x_ref_d2, 2 eta_q = mu_q / x_ref_q2, 2 eta_r = mu_r / x_ref_r2,
 * i.e. an NLMS normalised once, at the tuning point (cfg), instead of at every sample. Away from
 * that point (other speed or current) its effective step scales with |x|^2: the paper's argument
 * for NLMS. Weights start at zero; R starts nominal until est_adaline_set_r. */
#ifndef EST_ADALINE_H
#define EST_ADALINE_H

#include "est_common.h"

typedef struct {
    est_core_t core;
} est_adaline_t;

void est_adaline_init(est_adaline_t *e, const est_cfg_t *cfg);
void est_adaline_set_r(est_adaline_t *e, float r_s_ohm);
void est_adaline_step(est_adaline_t *e, const id_sample_t *s, est_out_t *out);

#endif
