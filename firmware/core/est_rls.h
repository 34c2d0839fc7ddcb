/* Recursive least squares estimator of L_d, L_q, psi_f (and R) with a forgetting factor, C28x-safe.
 * The same regressions as the Adaline estimators (est_common.h), each solved by its own 2-parameter
 * RLS in per-unit coordinates (theta_i = w_i / nominal_i, so float32 stays well conditioned):
 *   d axis: [R, L_q] with [i_d, -w i_q],  q axis: [L_d, psi_f] with [w i_d, w].
 * A parameter whose excitation guard is off this window is left out of the update (its input is
 * zeroed, its covariance row frozen); covariance diagonals are capped at p0 (no wind-up when a
 * direction is not excited under forgetting). Weights start at zero, P = p0 I. */
#ifndef EST_RLS_H
#define EST_RLS_H

#include "est_common.h"

typedef struct {
    est_core_t core;
    float p_d[4]; /* covariance of [R, L_q] (per-unit), row-major 2x2 */
    float p_q[4]; /* covariance of [L_d, psi_f] */
} est_rls_t;

void est_rls_init(est_rls_t *e, const est_cfg_t *cfg);
void est_rls_set_r(est_rls_t *e, float r_s_ohm);
void est_rls_step(est_rls_t *e, const id_sample_t *s, est_out_t *out);

#endif
