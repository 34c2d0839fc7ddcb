/* Shared parts of the online estimators of L_d, L_q, psi_f (and R) of paper A, C28x-safe.
 *
 * The estimators (est_rls.c, est_adaline.c, est_nlms.c) all work on the window samples of
 * id_window.h and on the same two regressions, derived from the steady-state voltage equations (6)
 * (not from the misprinted (18)-(27)), with the window's residual di/dt moved to the target side:
 *   d axis:  y_d = u_d - L_d^ di_d/dt            = R i_d + L_q (-w i_q)
 *   q axis:  y_q = u_q - L_q^ di_q/dt - R^ i_q   = L_d (w i_d) + psi_f w
 * L_q comes from the d equation, L_d and psi_f share the q equation (they separate only when i_d
 * varies: MTPA's i_d or the profile's d-axis excitation). R is identified at standstill by the
 * injection (r_inject.c) and refined online from the d equation once the others have converged.
 * Guards: no update while |w| < omega_min; L_d and the online R need |i_d| >= i_d_min, L_q needs
 * |i_q| >= i_q_min; estimates are clamped to [bound_lo, bound_hi] x nominal. */
#ifndef EST_COMMON_H
#define EST_COMMON_H

#include <stdint.h>
#include <stdbool.h>
#include "id_window.h"

#define EST_R   0u
#define EST_LD  1u
#define EST_LQ  2u
#define EST_PSI 3u
#define EST_N   4u

typedef struct {
    float nominal[EST_N];     /* motor file: r_s_ohm, l_d_h, l_q_h, psi_f_wb (bounds, scaling) */
    float bound_lo, bound_hi; /* estimates clamped to [lo, hi] x nominal */
    float omega_min_rad_s;    /* |mean w_e| below this: no update at all */
    float i_d_min_a;          /* |mean i_d| below this: L_d and R frozen */
    float i_q_min_a;          /* |mean i_q| below this: L_q frozen */
    float mu_d, mu_q;         /* LMS/NLMS step of the d and q regressions */
    float mu_r;               /* step of the online R refinement (normalised, 0: off) */
    float lambda;             /* RLS forgetting factor */
    float p0;                 /* RLS initial covariance, in per-unit of the nominal values */
    float x_ref_d2, x_ref_q2; /* LMS: squared norm of the regressors at the tuning point */
    float x_ref_r2;           /* LMS: squared i_d at the tuning point (online R) */
    float conv_tol; /* converged: L_d, L_q, psi_f within this fraction of their slow averages */
    uint16_t conv_min_updates; /* ... and at least this many updates */
} est_cfg_t;

/* What every estimator reports. */
typedef struct {
    float r_s_ohm, l_d_h, l_q_h, psi_f_wb;
    bool excited;     /* the last window updated L_d, L_q and psi_f */
    bool converged;   /* the estimates have settled */
    uint32_t updates; /* windows used */
} est_out_t;

/* Common state of an estimator (weights in SI units). */
typedef struct {
    est_cfg_t cfg;
    float w[EST_N];
    float slow[EST_N];
    float r_ref;    /* R of the injection (nominal before it): the online R's bounds */
    float i_d_mean; /* running mean of i_d over the excitation (LMS/NLMS: decorrelated L_d input) */
    bool i_d_mean_set;
    uint32_t updates;
    bool excited, converged, ever_converged;
} est_core_t;

/* Excitation of one window. */
typedef struct {
    bool any; /* |w| high enough for any update */
    bool ld;  /* L_d may be updated */
    bool lq;  /* L_q may be updated */
    bool psi; /* psi_f may be updated */
    bool r;   /* the online R refinement may run */
} est_excite_t;

/* Defaults for a motor: omega_min 40 rad/s, i_d_min 0.5 A, i_q_min 0.5 A, bounds [0, 3] x nominal,
 * the tuning point of paper A's identification run (1000 r/min, 5 A, +-2 A of i_d excitation). */
void est_cfg_default(est_cfg_t *c, float r_s_ohm, float l_d_h, float l_q_h, float psi_f_wb,
                     uint16_t pole_pairs);

void est_core_init(est_core_t *e, const est_cfg_t *cfg); /* zero weights (paper), R nominal */
void est_core_set_r(est_core_t *e, float r_s_ohm);       /* R from the standstill injection */
void est_core_excitation(const est_core_t *e, const id_sample_t *s, est_excite_t *x);
/* Targets with the current estimates: y_d (for R i_d + L_q x_lq) and y_q (for L_d x_ld + psi_f w). */
void est_core_targets(const est_core_t *e, const id_sample_t *s, float *y_d, float *y_q);
/* After an update: clamp, track the slow averages and the converged flag. */
void est_core_finish(est_core_t *e, const est_excite_t *x);
void est_core_out(const est_core_t *e, est_out_t *out);
/* LMS/NLMS on the q equation: L_d and psi_f share it, and the inputs w i_d and w are strongly
 * correlated (i_d = mean + excitation), which makes plain (N)LMS converge slowly along L_d and
 * couples the noise of the fast psi_f direction into L_d. The update direction is therefore taken in
 * the decorrelated inputs x1 = w (i_d - i_d_mean), x2 = w (weights L_d and psi_f + L_d i_d_mean):
 * the same model output, L_d x1 + (psi_f + L_d m) x2 = L_d w i_d + psi_f w. Returns x1 and updates
 * the running mean (call once per updating window). */
float est_core_x_ld_centered(est_core_t *e, const id_sample_t *s);

#endif
