/* Model-reference adaptive speed and angle estimator (paper B, eqs. (1)-(21)), generalised to
 * L_d != L_q and with the one-period computation delay in the model's voltage (docs/sensorless.md).
 *
 * Reference model: the motor itself, i.e. the measured currents i(k) turned into the estimated
 * frame at theta_hat(k). Adjustable model: the dq current model in the estimated frame, one step
 * from the measured i(k-1) with the voltage the inverter applied during [k-1, k) (decided at k-2:
 * the computation delay), at the frame's mid-period angle, and the adapted speed w_hat:
 *   i_d^(k) = i_d + Ts/L_d (u_d - R i_d + w_hat L_q i_q)
 *   i_q^(k) = i_q + Ts/L_q (u_q - R i_q - w_hat L_d i_d - w_hat psi_f)
 * In the estimated frame the true extended EMF E = w (psi_f + (L_d - L_q) i_d) lies at the angle
 * error d = theta - theta_hat from the q axis, so the model error e = i(k) - i^(k) is
 *   e_d = Ts/L_d E sin d,    e_q = Ts/L_q (w_hat psi_ex - E cos d)   (psi_ex = E / w)
 * The motor's EMF is read back from the error: E (sin d, cos d) with E_d = e_d L_d / Ts and
 * E_q = w_hat psi_ex - e_q L_q / Ts (after undoing the half-period turn of the model's increment),
 * and the error signal is its angle eps = atan2(E_d, E_q) = d: the gain does not depend on speed.
 * Adaptation: paper B's PI (20) and theta = int w (21), extended by the torque feed-forward
 * a_ff = 1.5 p^2 psi_ex i_q / J and a load-acceleration state a:
 *   w_hat' = a_ff + a + l2 eps,  a' = l3 eps,  theta_hat' = w_hat + l1 eps
 * with the three poles at -bw (l1 = 3 bw, l2 = 3 bw^2, l3 = bw^3); with J = 0 and l3 = 0 it is
 * paper B's PI. The frame tracks the EMF phasor: for w < 0 the rotor's d axis is its -d.
 * Below min_speed the EMF carries no usable information: the estimator holds its speed, keeps
 * integrating the angle and reports itself not locked. C28x-safe: float only. */
#ifndef MRAS_H
#define MRAS_H

#include <stdint.h>
#include <stdbool.h>

typedef struct {
    float ts_s;
    float bw_rad_s;        /* angle-loop bandwidth (0: 300 rad/s) */
    float min_speed_rad_s; /* electrical; not locked (and not adapting) below */
    float max_speed_rad_s; /* electrical; the estimate is clamped to +-this */
    float theta0_rad;      /* initial estimated angle */
    float r_s_ohm, l_d_h, l_q_h, psi_f_wb;
    float j_kgm2; /* inertia for the torque feed-forward (0: none) */
    uint16_t pole_pairs;
} mras_cfg_t;

typedef struct {
    float i_alpha_a, i_beta_a; /* measured at k */
    float u_alpha_v, u_beta_v; /* average stationary-frame voltage applied during [k-1, k) */
} mras_in_t;

typedef struct {
    float theta_e_rad;   /* estimated electrical angle at k, [0, 2 pi) */
    float omega_e_rad_s; /* estimated electrical speed */
    float eps_rad;       /* normalised error signal (sin of the angle error seen) */
    float confidence;    /* 0..1 */
    bool locked;
} mras_out_t;

typedef struct {
    mras_cfg_t cfg;
    float l1, l2, l3;               /* observer gains: 3 bw, 3 bw^2, bw^3 */
    float ff_gain;                  /* 1.5 p^2 / J: torque feed-forward */
    float theta_rad, omega_i_rad_s; /* angle at k; the speed estimate (observer state) */
    float acc_rad_s2;               /* load (and model error) acceleration state */
    float omega_rad_s;              /* the frame's speed over [k-1, k): w_hat + l1 eps */
    float i_al_prev, i_be_prev;     /* measured i(k-1) */
    float emf_f;        /* filtered |E| (V): the adaptation runs above min_speed psi_ex */
    float eps_f, e_w_f; /* filtered error signal; filtered EMF ratio |E| / (|w_hat| psi_ex) */
    uint32_t n;         /* steps since init */
    bool reverse;       /* w_hat < 0: the rotor's d axis is the frame's -d */
    bool locked;
} mras_t;

void mras_init(mras_t *m, const mras_cfg_t *cfg);
void mras_step(mras_t *m, const mras_in_t *in, mras_out_t *out);
/* The model's error for one step, in the estimated frame (exposed for the unit test):
 * e_d, e_q of i(k) against the adjustable model from i(k-1) (alpha/beta inputs, angle theta_mid
 * of the frame at mid-period, speed w). */
void mras_model_error(const mras_cfg_t *cfg, float i_al0, float i_be0, float i_al1, float i_be1,
                      float u_al, float u_be, float theta0_rad, float w_rad_s, float *e_d,
                      float *e_q);

#endif
