/* The current-control slot: one stage of the control period (docs/architecture.md). In: the
 * measured dq currents and their references, the angle and speed of the angle slot, the DC
 * voltage and the predictor's parameters. Out: either forced switch states (finite-control-set
 * controllers) or three duties (modulators), plus the average dq voltage applied during the
 * period, which estimators and observers consume.
 *
 * Occupants: the MPCC (mpcc.h, switch states) and FOC with SVPWM (foc.h, duties). A new occupant
 * adds a CC_KIND_x, a member of the union in cc_t and a case in cc_slot.c; nothing else in the
 * firmware changes. */
#ifndef CC_SLOT_H
#define CC_SLOT_H

#include <stdint.h>
#include <stdbool.h>

#include "mpcc.h"
#include "foc.h"
#include "proto_gen.h"

#define CC_KIND_MPCC PROTO_CURRENT_CTRL_MPCC /* config_ctrl current_ctrl */
#define CC_KIND_FOC  PROTO_CURRENT_CTRL_FOC

#define CC_OUT_STATES 0u /* s_a, s_b, s_c: upper switches forced for the whole period */
#define CC_OUT_DUTIES 1u /* duty_a, duty_b, duty_c: upper-switch on-time fractions, [0, 1] */

/* Parameters of the controller's plant model (nominal, scaled, or identified). */
typedef struct {
    float r_s_ohm, l_d_h, l_q_h, psi_f_wb;
} cc_params_t;

typedef struct {
    float i_d_a, i_q_a; /* measured at the sample instant k, in the angle slot's frame */
    float i_d_ref_a, i_q_ref_a;
    float theta_e_rad;          /* angle slot's electrical angle at k */
    float cos_theta, sin_theta; /* cosf, sinf of theta_e_rad (computed once per period) */
    float omega_e_rad_s;
    float v_dc_v;
    cc_params_t pred; /* the predictor's parameters (identification's output) */
} cc_in_t;

typedef struct {
    uint16_t mode;                /* CC_OUT_STATES or CC_OUT_DUTIES */
    uint16_t s_a, s_b, s_c;       /* CC_OUT_STATES: applied from k+1 on */
    float duty_a, duty_b, duty_c; /* CC_OUT_DUTIES: applied from k+1 on */
    float u_d_v, u_q_v;           /* dq voltage at theta_e_rad applied during [k, k+1) */
    float u_d_avg_v, u_q_avg_v;   /* the same as the dq average over [k, k+1) */
    float u_alpha_v, u_beta_v;    /* the same in the stationary frame (frame-free, for observers) */
    float i_d_pred_a, i_q_pred_a; /* the controller's prediction of i(k+1) (observers) */
} cc_out_t;

typedef struct {
    uint16_t kind;   /* CC_KIND_* */
    mpcc_cfg_t mpcc; /* CC_KIND_MPCC */
    foc_cfg_t foc;   /* CC_KIND_FOC */
} cc_cfg_t;

typedef struct {
    uint16_t kind;
    union {
        mpcc_t mpcc;
        foc_t foc;
    } u;
} cc_t;

bool cc_kind_known(uint16_t kind);
void cc_init(cc_t *c, const cc_cfg_t *cfg); /* an unknown kind falls back to CC_KIND_MPCC */
bool cc_uses_duties(const cc_t *c);
void cc_step(cc_t *c, const cc_in_t *in, cc_out_t *out);
void cc_reset(cc_t *c); /* forget the applied output (PWM was off) */
/* The occupant a segment asks for: its cc_foc / cc_mpcc flag (profile_segment.flags), else
 * `fallback` (the profile's choice, or the running segment's). */
uint16_t cc_segment_kind(uint16_t seg_flags, uint16_t fallback);
/* Hand the slot to another occupant while the PWM runs (a segment that names its current
 * controller): the new one takes the voltage the old one applies during the running period as
 * already applied, and a PI occupant starts its integrators where its first command continues
 * the old occupant's mean dq voltage (u_d_mean_v, u_q_mean_v: a low-pass of cc_out's u_*_avg_v
 * over about a millisecond), so neither the voltage nor the current steps. `in` is this period's
 * input (currents, speed, v_dc, predictor parameters). Same kind or an unknown kind: nothing
 * changes. */
void cc_hand_over(cc_t *c, const cc_cfg_t *cfg, uint16_t kind, const cc_in_t *in, float u_d_mean_v,
                  float u_q_mean_v);
/* Switch-state code applied during the running period (bit0 s_a, bit1 s_b, bit2 s_c; what a
 * capture logs with i(k)); 0 for a duty-cycle occupant. */
uint16_t cc_applied_code(const cc_t *c);

#endif
