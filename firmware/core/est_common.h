/* Shared parts of the online estimators of L_d, L_q, psi_f (and R) of paper A, C28x-safe.
 *
 * The estimators (est_rls.c, est_adaline.c, est_nlms.c) all work on the window samples of
 * id_window.h and on the same two regressions, derived from the steady-state voltage equations (6)
 * (not from the misprinted (18)-(27)), with the window's residual L di/dt moved to the target side:
 *   d axis:  y_d = u_d - l_d . phi + r_off m       = R m + s (i_d - m) + L_q (-w i_q)
 *   q axis:  y_q = u_q - l_q . phi - R i_q         = L_d (w i_d) + psi_f w
 * with phi = (di_d/dt, di_q/dt, x di_d/dt, x di_q/dt), x = i_d - m, m the running mean of i_d: the
 * L di/dt terms carry incremental inductances learnt from the current ripple (est_core_track_inc),
 * which on a saturating machine differ from the apparent ones identified and between the
 * excitation's levels. L_q comes from the d equation, L_d and psi_f share the q equation (they
 * separate only when i_d varies: MTPA's i_d or the profile's d-axis excitation). R is identified
 * at standstill by the injection (r_inject.c); online, the d equation's slope s along the
 * excitation follows its changes (R = s - r_off, the offset calibrated at each operating point:
 * the slope is R - w dpsi_q/di_d plus the inverter residual's share, docs/identification.md).
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
    float i_d_exc_ref_a;      /* NLMS: the i_d excitation's amplitude the q step was tuned at, A */
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
#define EST_INC_N 4u /* di_d/T, di_q/T, x di_d/T, x di_q/T */
/* The L di/dt terms are learnt once the estimates have settled or after this many windows,
 * whichever comes first: without them L_d's window noise can keep the estimates from ever
 * settling to within conv_tol. */
#define EST_INC_WARM_N 64u

typedef struct {
    est_cfg_t cfg;
    float w[EST_N];
    float slow[EST_N];
    float r_ref;    /* R of the injection (nominal before it): the online R's bounds */
    float i_d_mean; /* running mean of i_d over the excitation (LMS/NLMS: decorrelated L_d input) */
    bool i_d_mean_set;
    /* The window's L di/dt terms with incremental inductances learnt from the current ripple
     * (est_core_track_inc), each linear in the window's i_d about its running mean (x): d equation
     * (l_d[0] + l_d[2] x) di_d + (l_d[1] + l_d[3] x) di_q, q equation likewise with l_q. */
    float l_d[EST_INC_N], l_q[EST_INC_N];
    float p_inc[EST_INC_N][EST_INC_N]; /* their RLS covariance (shared regressor) */
    /* The online R relative to the operating point (est_core_r_offset): at one speed the d
     * equation's slope along the i_d excitation is R - w dpsi_q/di_d plus the inverter residual's
     * share, not R. w[EST_R] is that slope; R = w[EST_R] - r_off, r_off calibrated at each
     * operating point while R is held. */
    float r_off, r_hold, r_off_sum;
    float op_w_rad_s, op_i_q_a; /* operating point of the calibration */
    float w_f_rad_s, i_q_f_a;   /* the operating point now: w and i_q over about 32 windows */
    uint16_t r_cal_n;           /* windows into the calibration */
    uint16_t op_away_n;         /* consecutive windows away from the calibration's point */
    uint16_t r_state;           /* EST_R_IDLE, EST_R_CAL, EST_R_TRACK */
    bool r_cal_new;             /* a calibration has just begun (RLS opens R's covariance) */
    uint32_t updates;
    bool excited, converged, ever_converged;
} est_core_t;

#define EST_R_IDLE  0u /* R held at the injection's value, no online refinement yet */
#define EST_R_CAL   1u /* R held; r_off follows the slope at this operating point */
#define EST_R_TRACK 2u /* r_off frozen; R follows the slope's changes */

/* Excitation of one window. */
typedef struct {
    bool any;                   /* |w| high enough for any update */
    bool ld;                    /* L_d may be updated */
    bool lq;                    /* L_q may be updated */
    bool psi;                   /* psi_f may be updated */
    bool r;                     /* the online R refinement may run */
    float omega_e_rad_s, i_q_a; /* the window's operating point */
} est_excite_t;

/* Defaults for a motor: omega_min 40 rad/s, i_d_min 0.5 A, i_q_min 0.5 A, bounds [0, 3] x nominal,
 * the tuning point of paper A's identification run (1000 r/min, 5 A, +-2 A of i_d excitation). */
void est_cfg_default(est_cfg_t *c, float r_s_ohm, float l_d_h, float l_q_h, float psi_f_wb,
                     uint16_t pole_pairs);

void est_core_init(est_core_t *e, const est_cfg_t *cfg); /* zero weights (paper), R nominal */
void est_core_set_r(est_core_t *e, float r_s_ohm);       /* R from the standstill injection */
void est_core_excitation(const est_core_t *e, const id_sample_t *s, est_excite_t *x);
/* Targets with the current estimates: y_d (for w[EST_R] i_d + L_q x_lq) and y_q (for
 * L_d x_ld + psi_f w). The d target carries r_off i_d_mean, so that the slope w[EST_R] multiplies
 * the excitation and R the mean: y_d = u_d - L di/dt = R m + w[EST_R] (i_d - m) + L_q x_lq. */
void est_core_targets(const est_core_t *e, const id_sample_t *s, float *y_d, float *y_q);
/* The resistance (w[EST_R] - r_off) the estimators report and the q target uses. */
float est_core_r(const est_core_t *e);
/* Learns the incremental inductances of the L di/dt terms from the window's residuals (call once
 * per window with x->any, before the estimator's own update). */
void est_core_track_inc(est_core_t *e, const id_sample_t *s);

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
