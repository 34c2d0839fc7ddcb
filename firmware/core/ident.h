/* Online identification as one object (docs/identification.md): the standstill R injection, the
 * window averaging, an array of estimators behind one operations table, and the predictor's feed
 * (its output). The firmware calls, per control period,
 *   ident_d_ref()        the d-current reference with the identification's excitation,
 *   ident_predictor()    the parameters the current controller's predictor uses now,
 *   ident_step()         after the current controller, with the applied average voltage;
 * and reads ident_report() for the parameter frames. ident_step's out tells when R was identified
 * (the caller raises the event). */
#ifndef IDENT_H
#define IDENT_H

#include <stdint.h>
#include <stdbool.h>

#include "cc_slot.h"
#include "est_common.h"
#include "est_rls.h"
#include "est_adaline.h"
#include "est_nlms.h"
#include "id_window.h"
#include "r_inject.h"

/* the estimators, index = PROTO_ESTIMATOR_x - 1 */
#define IDENT_N_EST       3u
#define IDENT_EST_RLS     0u
#define IDENT_EST_ADALINE 1u
#define IDENT_EST_NLMS    2u

#define IDENT_R_SETTLE_FRAC 0.2f /* identify_r: part of each current level skipped (settling) */
#define IDENT_STEP_A        0.5f /* an i_d reference step above this skips the window */
/* ... and the windows of the next periods (the controller's transient) */
#define IDENT_STEP_HOLD 5u

/* One estimator behind the operations table. */
typedef struct {
    void (*init)(void *est, const est_cfg_t *cfg);
    void (*set_r)(void *est, float r_s_ohm);
    void (*step)(void *est, const id_sample_t *s, est_out_t *out);
} est_ops_t;

typedef struct {
    cc_params_t nominal;    /* the motor file's values */
    cc_params_t pred_scale; /* predictor = nominal: nominal x these factors (profile mismatch) */
    uint16_t pole_pairs;
    float ts_s;
    uint16_t id_window;   /* control periods per estimator window */
    bool identify;        /* run the estimators */
    uint16_t predictor;   /* 0: nominal; k: estimator k-1 feeds the predictor once converged */
    bool have_injection;  /* the profile has an identify_r segment */
    float angle_bias_rad; /* the angle source's mean lag (the encoder's half count, electrical) */
} ident_cfg_t;

/* The running segment as the identification sees it. */
typedef struct {
    bool identify_r;           /* a standstill R-injection segment */
    bool hold;                 /* the estimators hold their values */
    float inject_a, inject_hz; /* identify_r: level; run: square-wave excitation of i_d */
    uint32_t tick, ticks;      /* control periods into the segment, its length */
} ident_seg_t;

typedef struct {
    float i_d_a, i_q_a;         /* measured at k */
    float u_d_avg_v, u_q_avg_v; /* average dq voltage applied during [k, k+1) (cc_out_t) */
    float theta_e_rad, omega_e_rad_s;
    float i_a_a, i_b_a, i_c_a;
    float i_d_ref_a; /* this period's d reference (steps skip the window) */
} ident_in_t;

typedef struct {
    bool r_identified_now; /* the injection ended in this period with r_s_ohm */
    float r_s_ohm;
} ident_out_t;

typedef struct {
    ident_cfg_t cfg;
    est_rls_t rls;
    est_adaline_t ada;
    est_nlms_t nlms;
    const est_ops_t *ops[IDENT_N_EST];
    void *est[IDENT_N_EST];
    est_out_t out[IDENT_N_EST];
    idw_t idw;
    rinj_t rinj;
    rinj_out_t rinj_out;
    bool r_identified;
    bool r_injecting; /* an identify_r segment is running */
    float r_ident_ohm;
    bool pred_latched; /* the chosen estimator converged once: it feeds the predictor */
    float id_ref_prev_a;
    bool idw_step_seen;    /* the running window holds an i_d reference step */
    uint16_t id_step_hold; /* periods of current transient still to come */
} ident_t;

void ident_init(ident_t *id, const ident_cfg_t *cfg);
/* d-current reference: identify_r's level (inject_a over the first half, inject_a / 2 over the
 * second), or i_d_base_a plus the segment's square-wave excitation. */
float ident_d_ref(const ident_t *id, const ident_seg_t *seg, float i_d_base_a);
/* The predictor's parameters now (latches the chosen estimator once it converged). */
void ident_predictor(ident_t *id, cc_params_t *out);
void ident_step(ident_t *id, const ident_seg_t *seg, const ident_in_t *in, ident_out_t *out);
/* Estimator slot k (0 .. IDENT_N_EST-1) as reported: its estimates, with the R the injection
 * knows while it runs, 0 before it (R unknown), then the estimator's own. */
void ident_report(const ident_t *id, uint16_t k, est_out_t *out);
bool ident_nominal_feeds(const ident_t *id); /* the predictor runs on the (scaled) nominal values */
/* Once the chosen estimator has converged (the predictor's latch): true, and its L_d, L_q, psi_f
 * in *out for the other parameter-dependent stages (MTPA, the dither); false before. */
bool ident_converged_params(const ident_t *id, cc_params_t *out);

#endif
