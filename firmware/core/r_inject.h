/* Stator resistance by d-axis current injection at standstill (paper A, (29)-(34)), C28x-safe.
 *
 * At w = 0 and in steady state the dq voltage equations with the inverter's error voltage are (32)
 *   u_d = R i_d - V_dead D_d,    u_q = R i_q - V_dead D_q,
 *   D_dq = Park_theta(Clarke(sgn i_a, sgn i_b, sgn i_c))   (amplitude-invariant Clarke),
 * so V_dead is the error voltage per phase. (30) as printed mixes signs and scales: its q row
 * must read -sin(theta), -sin(theta - 2pi/3), -sin(theta + 2pi/3) (the printed last entry
 * sin(theta - pi/3) equals -sin(theta + 2pi/3)), and its factor 2 only rescales V_dead.
 * Eliminating V_dead from one sample gives (34):
 *   R = (u_d D_q - u_q D_d) / (i_d D_q - i_q D_d).
 * It is 0/0 when the current vector lies along D, e.g. a pure d current with the rotor at a
 * multiple of 60 degrees electrical (phase currents I, -I/2, -I/2 at theta = 0: D = (4/3, 0)).
 * This object therefore solves (32) by least squares over all periods of the injection
 * (two unknowns R, V_dead; (34) is its one-sample case), which stays well posed at any angle when
 * the injection uses two current levels (same signs, so the same D, different |i|):
 *   [S_ii  -S_iD] [R     ]   [ S_ui]      S_xy = sum over periods of x_d y_d + x_q y_q
 *   [-S_iD  S_DD] [V_dead] = [-S_uD]
 * If the system is still singular (one level along D) it falls back to R = S_ui / S_ii, i.e. it
 * trusts the voltage's own dead-time compensation (flag separable = false).
 * The voltage is the period average the firmware applied (with or without its dead-time model):
 * V_dead is then what the firmware's compensation left over (or all of it without compensation).
 * FCS-MPC: the sampled current ripples by about an ampere and the applied vector is hundreds of
 * volts, correlated with that ripple; where a phase current is small its sign flips with the
 * ripple, so (32) per period correlates huge L di/dt terms with D and is biased. (32) is a
 * steady-state equation: u, i are therefore averaged over windows of n_window periods and D is taken
 * from the signs of the window's mean phase currents; the LS runs over the windows.
 * The window means are exact integrals of the dq model (as in id_window.c): the current mean is the
 * trapezoidal one (the plain mean of the samples i(k) misses half of each period's ripple step, and
 * that step is correlated with the period's voltage: -7.6 % on R with the levels 10 A / 5 A), and
 * the residual L (i_end - i_start)/T of each window is removed with the nominal inductances
 * (l_d_h, l_q_h; 0 leaves it in). rinj_gap() drops the running window where the samples stop being
 * consecutive (the settling time of the next level). */
#ifndef R_INJECT_H
#define R_INJECT_H

#include <stdint.h>
#include <stdbool.h>

typedef struct {
    float sep_min;      /* minimum 1 - S_iD^2 / (S_ii S_DD) to solve for V_dead (default 1e-3) */
    uint16_t n_window;  /* periods averaged before each LS sample (default 20) */
    float ts_s;         /* control period (default 50 us) */
    float l_d_h, l_q_h; /* nominal inductances for the window's residual L di/dt (0: none) */
} rinj_cfg_t;

typedef struct {
    float i_d_a, i_q_a;        /* sampled at k */
    float u_d_v, u_q_v;        /* period-average voltage over [k, k+1) */
    float theta_e_rad;         /* at k */
    float i_a_a, i_b_a, i_c_a; /* phase currents at k (unused: D from the window means) */
} rinj_in_t;

typedef struct {
    float r_s_ohm;  /* running estimate (0 until the first window) */
    float v_dead_v; /* identified error voltage per phase */
    bool separable; /* V_dead was eliminated (two levels or a current off the D direction) */
    uint32_t n;     /* windows used */
} rinj_out_t;

typedef struct {
    rinj_cfg_t cfg;
    float s_ii, s_id, s_dd, s_ui, s_ud; /* LS sums over windows */
    uint32_t n;
    /* running window: sums over its periods, and its first sample */
    uint16_t w_count;
    float w_id, w_iq, w_ud, w_uq, w_c, w_s;
    float w_id0, w_iq0;
} rinj_t;

void rinj_init(rinj_t *r, const rinj_cfg_t *cfg);
void rinj_reset(rinj_t *r);
void rinj_gap(
    rinj_t *r); /* the next sample does not follow the last one: drop the running window */
void rinj_step(rinj_t *r, const rinj_in_t *in, rinj_out_t *out);
void rinj_result(const rinj_t *r, rinj_out_t *out);

#endif
