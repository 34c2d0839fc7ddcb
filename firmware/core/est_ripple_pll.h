/* Ripple/saliency PLL (paper A section 3, corrected; docs/sensorless.md): angle and speed of an
 * IPMSM from the current ripple that the current controller's own switching makes.
 *
 * Every control period, in the frame of the estimated angle at the middle of the period just
 * ended [k-1, k):
 *   measured:  di  = Park(i(k) - i(k-1))                       (rotation of the frame included)
 *   predicted: di^ = Ts Gamma(i_m) U + w Ts J i_m,   U = u - R i_m - w J psi(i_m)
 * with i_m = (i(k) + i(k-1))/2 and u the inverter's average voltage over the period (constant in
 * alpha-beta): the midpoint rule, so the forward-Euler bias of a one-step prediction at speed
 * (a term Ts^2 w Gamma J L Gamma U/2, correlated with U) does not enter. The error e = di - di^
 * (with the current-sample delay tau: the sampled step holds tau of the previous period's slope,
 * -tau Gamma (U - U_prev) is added to the prediction, tau estimated online by NLMS on e while the
 * confidence is high) goes through the phase detector (ripple_err.h): sin 2d with d = theta - theta^, normalised by a
 * running mean of Ts D^2 |U|^2 (a ratio of means, so that periods of a zero vector add no noise).
 *
 * Tracking observer with torque feed-forward (triple pole at -bw):
 *   theta^ += Ts (w^ + l1 d^),  w^ += Ts (p T_e(i)/J + a^ + l2 d^),  a^ += Ts l3 d^
 *   d^ = sin(2d)/2,  l1 = 3 bw,  l2 = 3 bw^2,  l3 = bw^3
 * a^ is the unknown acceleration (load, friction). The speed it reports (and the speed loop
 * closes on) is w^ low-passed with tau = RPLL_SPEED_TAU_BW / bw, with tau (p T_e/J + a^) added:
 * the detector's noise that w^ carries near bw is cut, and a ramp or a settled load (the
 * acceleration the observer knows) leaves no lag (docs/sensorless.md, "Speed output").
 * The confidence cos 2d is a running mean of
 * 1 + cn/norm. The detector cannot tell theta from theta + pi (polarity.h resolves it).
 *
 * Excitation: with excite_a > 0 the estimator asks for a d-axis current of +-excite_a alternating
 * every control period (at half the control rate: no torque at i_q = 0, no frequency that the
 * speed loop or the plant's mechanics pass), so that the current controller applies an active
 * vector in most periods whatever the load; the detector's noise falls with the number of
 * informative periods (docs/sensorless.md, "Excitation"). Without it (or with too little ripple
 * even so) a 1 A square wave at 1 kHz is the fallback. */
#ifndef EST_RIPPLE_PLL_H
#define EST_RIPPLE_PLL_H

#include <stdint.h>
#include <stdbool.h>

#include "ripple_err.h"

#define RPLL_BW_DEFAULT_RAD_S    400.0f
#define RPLL_NORM_TAU_DEFAULT_S  2.0e-3f
#define RPLL_CONF_TAU_DEFAULT_S  10.0e-3f
#define RPLL_TAU_GAIN            2.0e-3f /* NLMS gain of the sample-delay estimate */
#define RPLL_SPEED_TAU_BW        2.4f    /* speed output's time constant x bw */
#define RPLL_HP_TAU_S            1.0e-3f /* running means removed from e and U */
#define RPLL_EXCITE_A            1.0f    /* d-axis square wave when the ripple is too small */
#define RPLL_EXCITE_HALF_PERIODS 10u     /* 1 kHz at 20 kHz */

typedef struct {
    float ts_s;
    uint16_t pole_pairs;
    float r_s_ohm, l_d_h, l_q_h, psi_f_wb, j_kgm2; /* nominal model (flux, torque) */
    rerr_gamma_t gamma;                            /* inverse incremental inductances */
    float bw_rad_s;                                /* observer poles at -bw (0: default) */
    float norm_tau_s;                              /* normaliser time constant (0: default) */
    float conf_tau_s;                              /* confidence time constant (0: default) */
    bool torque_ff;                                /* feed the model torque forward */
    float excite_a; /* d-axis excitation alternating every period, A (0: only the fallback) */
} rpll_cfg_t;

typedef struct {
    float i_alpha_a, i_beta_a; /* measured at k */
    float u_alpha_v, u_beta_v; /* inverter's average voltage over [k-1, k) */
    bool u_valid;              /* false: PWM was off during [k-1, k) (no information) */
} rpll_in_t;

typedef struct {
    float theta_e_rad; /* at k, [0, 2pi) */
    float omega_e_rad_s;
    float err_rad;      /* this period's detector output sin(2d)/2 (about d near lock) */
    float conf;         /* running mean of cos 2d: 1 locked, 0 at d = pi/4, -1 at pi/2 */
    bool excited;       /* the normaliser is above its floor (the ripple carries information) */
    float di_d_a;       /* d-axis current change over the period, rotation removed */
    float u_d_v;        /* voltage across the d inductance U_d */
    float i_d_mid_a;    /* mid-period d current */
    float torque_nm;    /* model torque at the mid-period current */
    float i_d_excite_a; /* fallback square wave the estimator asks for (0: enough ripple) */
    float i_d_hf_a;     /* the excitation alternating every period (+-excite_a) */
} rpll_out_t;

typedef struct {
    rpll_cfg_t cfg;
    float l1, l2, l3;
    float th, w, acc;         /* angle at k, speed, disturbance acceleration */
    float w_f, tau_w_s, k_wf; /* speed output: filtered, lag-compensated; its time constant */
    float norm_f, conf_f, norm_floor;
    float k_norm, k_conf, k_hp, norm_excite;
    float m_ed, m_eq, m_ud, m_uq;          /* running means of e and U */
    float u_prev_d, u_prev_q, r2_f, tau_s; /* current-sample delay: last U, regressor power, tau */
    uint16_t exc_tick;
    float hf_sign; /* sign of the next excitation period */
    float i_al_prev, i_be_prev;
    bool have_prev;
} rpll_t;

void rpll_init(rpll_t *e, const rpll_cfg_t *cfg);
/* Restart at this angle and speed (disturbance and history cleared). */
void rpll_reset(rpll_t *e, float theta_e_rad, float omega_e_rad_s);
void rpll_step(rpll_t *e, const rpll_in_t *in, rpll_out_t *out);
/* Turn the estimate by half a turn (the polarity test found the other magnet pole). */
void rpll_flip(rpll_t *e);
/* Move the estimate toward theta by at most max_step_rad (bumpless alignment by the hybrid). */
void rpll_pull(rpll_t *e, float theta_e_rad, float omega_e_rad_s, float frac);

#endif
