/* Finite-control-set model predictive current control (paper A, eqs. (2)-(5)), C28x-safe.
 *
 * Once per control period k (after sampling i(k) and theta(k)):
 *   1. predict i(k+1) with the vector chosen by the previous call, which the inverter applies during
 *      [k, k+1) (one-period computation delay; delay compensation),
 *   2. for every candidate switching state predict i(k+2) and evaluate
 *      J = (i_d* - i_d(k+2))^2 + rho (i_q* - i_q(k+2))^2,
 *   3. return the best state; the caller applies it from k+1 on.
 * Additions to paper A (docs/control.md): an offset-compensation integrator that shifts the
 * references the cost sees (removes FCS's steady-state offset and low-speed dead band; k_int = 0
 * gives plain paper A), and a dead-time/device-drop model in the prediction.
 * The model is the physical dq model (the paper's (1)-(3) carry a sign typo in the q-axis cross
 * coupling; see docs/control.md):
 *   L_d di_d/dt = u_d - R i_d + w L_q i_q
 *   L_q di_q/dt = u_q - R i_q - w L_d i_d - w psi_f
 * Switch-state code used throughout (same as the capture frame's s_abc):
 *   code = s_a | s_b << 1 | s_c << 2. */
#ifndef MPCC_H
#define MPCC_H

#include <stdint.h>
#include <stdbool.h>
#include "fw_types.h"

/* Candidate set (cfg.cand_set). */
#define MPCC_CAND_ALL8     0u /* all 8 switching states (7 distinct vectors), paper A (5) */
#define MPCC_CAND_ADJACENT 1u /* paper A Table 1: the 3 states one switch change away */

/* Dead-time / device-drop model used in the prediction and in out->u_d_v/u_q_v (cfg.dt_model).
 * Both are off when dead_time_s == 0 and v_drop_v == 0. */
/* MPCC_DT_SWITCHING (default, exact for FCS): per switching event of a leg, turned on with
 * i_x > 0 it loses v_dc dead_time, turned off with i_x < 0 it gains it (averaged over the
 * period); plus -v_drop sign(i_x) */
#define MPCC_DT_SWITCHING 0u
/* MPCC_DT_AVERAGE: PWM-style average, per phase -V_dt sign(i_x), V_dt = v_dc dead_time/ts +
 * v_drop (assumes one on/off pair per period: over-compensates FCS switching, see
 * docs/control.md) */
#define MPCC_DT_AVERAGE 1u

/* Delay compensation (cfg.delay_comp). OFF exists for tests and comparisons only. */
#define MPCC_DELAY_COMP_ON  0u
#define MPCC_DELAY_COMP_OFF 1u

#define MPCC_K_INT_DEFAULT_RAD_S 2000.0f
#define MPCC_INT_MAX_DEFAULT_A   1.5f

typedef struct {
    float ts_s;        /* control period */
    float rho;         /* q-axis weighting factor of the cost (paper A: 1) */
    float dead_time_s; /* inverter dead time known to the firmware (0: no compensation) */
    float v_drop_v;    /* device on-state drop known to the firmware (0: none) */
    float i_dt_a;      /* current band of the smooth sign sigma(i / i_dt) (0: ideal sign) */
    /* Added options. Call mpcc_cfg_default() first, then set the fields above. (A zero-initialised
     * cfg selects the enum defaults but leaves the offset compensation off: plain paper A.)
     * Unknown enum values fall back to the defaults. */
    uint16_t cand_set;   /* MPCC_CAND_* (default ALL8) */
    uint16_t dt_model;   /* MPCC_DT_* (default SWITCHING) */
    uint16_t delay_comp; /* MPCC_DELAY_COMP_* (default ON) */
    float k_int_rad_s;   /* offset compensation: bandwidth of an integrator on the sampled current
                            error that shifts the references the cost sees (0: off = plain paper A).
                            Removes the steady-state offset and the low-speed dead band of
                            single-vector FCS; see docs/control.md */
    float int_max_a;     /* clamp of that integrator (A) */
} mpcc_cfg_t;

typedef struct {
    mpcc_cfg_t cfg;
    uint16_t sw_prev; /* state chosen by the previous call = applied during the current period */
    uint16_t
        sw_prev2; /* state applied during the previous period (for the switching dead-time model) */
    float int_d_a, int_q_a; /* offset-compensation integrators (reference shift, A) */
    /* cached reciprocals of the predictor inductances (recomputed when they change) */
    float l_d_cached_h, l_q_cached_h, inv_l_d, inv_l_q;
    float inv_i_dt; /* 1 / cfg.i_dt_a, 0 for the ideal sign */
    /* a handover from a modulator (mpcc_take_over): the stationary voltage applied during the
     * running period, used once in place of sw_prev's vector */
    bool ext_applied;
    float ext_u_alpha_v, ext_u_beta_v;
} mpcc_t;

typedef struct {
    float i_d_a, i_q_a; /* measured at the sample instant k */
    float i_d_ref_a, i_q_ref_a;
    float theta_e_rad;   /* electrical angle at k */
    float omega_e_rad_s; /* electrical speed, assumed constant over the horizon */
    float v_dc_v;
    /* predictor parameters (nominal or identified) */
    float r_s_ohm, l_d_h, l_q_h, psi_f_wb;
} mpcc_in_t;

typedef struct {
    uint16_t s_a, s_b, s_c; /* state chosen now: the caller applies it from k+1 on */
    /* dq voltage (at theta_e_rad) of the vector applied during THIS period [k, k+1), i.e. chosen
     * by the previous call, including the dead-time/drop distortion as the firmware models it */
    float u_d_v, u_q_v;
    float cost; /* J of the chosen state */
    /* Added outputs */
    uint16_t s_abc_applied;     /* code of the state applied during THIS period (what a capture
                                     should log with i(k)); bit0 s_a, bit1 s_b, bit2 s_c */
    uint16_t s_abc_next;        /* code of the chosen state (= s_a | s_b << 1 | s_c << 2) */
    float u_d_avg_v, u_q_avg_v; /* the same voltage rotated at theta + w Ts / 2: the dq average
                                     over [k, k+1) (better for estimators at speed) */
    float i_d_k1_a, i_q_k1_a;   /* predicted i(k+1) (for the ripple/prediction-error observers) */
    float i_d_k2_a, i_q_k2_a;   /* predicted i(k+2) with the chosen state */
} mpcc_out_t;

void mpcc_cfg_default(mpcc_cfg_t *cfg); /* ts 50 us, rho 1, no dead-time compensation */
void mpcc_init(mpcc_t *m, const mpcc_cfg_t *cfg);
void mpcc_step(mpcc_t *m, const mpcc_in_t *in, mpcc_out_t *out);
/* The same with cosf/sinf of in->theta_e_rad given (a caller that has them for its Park transform
 * saves the pair). */
void mpcc_step_cs(mpcc_t *m, const mpcc_in_t *in, float cos_th, float sin_th, mpcc_out_t *out);
void mpcc_reset(mpcc_t *m); /* forget the applied state (call when the PWM was off) */
/* Take over from another current controller while the PWM runs: the voltage it applies during
 * the running period (stationary frame, V) replaces the applied state's vector in the next
 * step's delay compensation; the state counted as applied for the switching and dead-time
 * models is the zero vector. */
void mpcc_take_over(mpcc_t *m, float u_alpha_v, float u_beta_v);

/* Normalised alpha/beta voltage of a switch-state code (multiply by v_dc). */
void mpcc_vector(uint16_t code, float *u_alpha_per_vdc, float *u_beta_per_vdc);

#endif
