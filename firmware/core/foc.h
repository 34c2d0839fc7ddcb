/* Field-oriented current control (paper B): PI current loops in dq with decoupling and
 * anti-windup, space-vector PWM as three duties, dead-time compensation (docs/sensorless.md).
 *
 * Timing (one-period computation delay): at the sample k the duties computed at k-1 are being
 * applied during [k, k+1); the duties computed now apply during [k+1, k+2). So the controller
 *   1. predicts i(k+1) from i(k) and the voltage applied during [k, k+1) (delay compensation),
 *   2. runs the PI on the error at k+1 with the decoupling feed-forward
 *        u_d = PI_d(i_d* - i_d(k+1)) - w L_q i_q(k+1)
 *        u_q = PI_q(i_q* - i_q(k+1)) + w (L_d i_d(k+1) + psi_f)
 *      (the PI's integral carries the resistive drop),
 *   3. limits |u| to the linear range v_dc / sqrt(3) (d axis first); while it cuts, the
 *      integrators do not integrate and stay within what the range allows (anti-windup),
 *   4. turns u to the stationary frame at theta + 1.5 w Ts (the middle of [k+1, k+2)) and
 *      modulates it: min-max zero-sequence injection (= SVPWM) and per-leg dead-time
 *      compensation d += (Td / Ts + V_drop / v_dc) sigma(i_x).
 * Gains from the plant's nominal L and R for a first-order closed loop of bandwidth bw (the PI
 * zero cancels the R/L pole): kp = bw L, ki = bw R (V/A/s). C28x-safe: float only. */
#ifndef FOC_H
#define FOC_H

#include <stdint.h>
#include <stdbool.h>

typedef struct {
    float ts_s;        /* control = PWM period (one carrier period per control period) */
    float bw_rad_s;    /* current-loop bandwidth (0: 2 pi / (20 Ts)) */
    float dead_time_s; /* compensated dead time per edge (0: none) */
    float v_drop_v;    /* compensated device drop */
    float i_dt_a;      /* current band of the compensation's smooth sign (0: ideal sign) */
} foc_cfg_t;

typedef struct {
    foc_cfg_t cfg;
    float x_d_v, x_q_v;         /* PI integrators (voltage) */
    float u_al_app, u_be_app;   /* stationary voltage applied during the running period */
    float u_al_next, u_be_next; /* computed last call: applied during the next period */
} foc_t;

typedef struct {
    float i_d_a, i_q_a; /* measured at k */
    float i_d_ref_a, i_q_ref_a;
    float cos_theta, sin_theta; /* angle at k */
    float omega_e_rad_s;
    float v_dc_v;
    float r_s_ohm, l_d_h, l_q_h, psi_f_wb; /* the predictor's parameters */
} foc_in_t;

typedef struct {
    float duty_a, duty_b, duty_c; /* applied from k+1 on */
    float u_d_v, u_q_v;           /* voltage applied during [k, k+1) at theta(k) */
    float u_d_avg_v, u_q_avg_v;   /* the same at theta + w Ts / 2 */
    float u_alpha_v, u_beta_v;    /* the same, stationary */
    float i_d_k1_a, i_q_k1_a;     /* predicted i(k+1) */
    float u_d_cmd_v, u_q_cmd_v;   /* the voltage commanded now (after the limit) */
    bool limited;
} foc_out_t;

void foc_cfg_default(foc_cfg_t *cfg);
void foc_init(foc_t *c, const foc_cfg_t *cfg);
void foc_reset(foc_t *c);
/* Take over from another current controller while the PWM runs: (u_alpha_v, u_beta_v) is the
 * voltage it applies during the running period; the integrators start at (x_d_v, x_q_v), chosen
 * by the caller so that the first command continues the previous occupant's mean voltage. */
void foc_take_over(foc_t *c, float u_alpha_v, float u_beta_v, float x_d_v, float x_q_v);
void foc_step(foc_t *c, const foc_in_t *in, foc_out_t *out);
/* Gains of the design (exposed for tests): kp in V/A, ki in V/(A s). */
void foc_gains(const foc_cfg_t *cfg, float r_ohm, float l_h, float *kp, float *ki);

#endif
