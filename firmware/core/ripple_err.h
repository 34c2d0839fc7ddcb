/* The saliency phase detector of the ripple PLL (docs/sensorless.md, "Ripple/saliency PLL").
 *
 * Over one control period the current changes by Ts*Gamma*U in the rotor frame, where U is the
 * voltage across the inductances (u - R i - w J psi) and Gamma the inverse incremental inductance
 * matrix. Predicted in an estimated frame that lags the rotor by d = theta - theta_hat, the
 * prediction error is e = Ts (R(d) Gamma R(d)^T - Gamma) U. Writing Gamma = S I + D (cos 2g C +
 * sin 2g X) (C = diag(1, -1), X = [[0, 1], [1, 0]], g the cross-saturation angle of its principal
 * axes), the two projections
 *     num_s = e_q U_d + e_d U_q,   num_c = e_d U_d - e_q U_q
 * are Ts D |U|^2 times (sin(2g + 2d) - sin 2g) and (cos(2g + 2d) - cos 2g); rotated back by 2g
 * they give, with Dc = D cos 2g and Ds = D sin 2g (no square root),
 *     sn = num_s Dc - num_c Ds = Ts D^2 |U|^2 sin 2d
 *     cn = num_c Dc + num_s Ds = Ts D^2 |U|^2 (cos 2d - 1)
 *     norm = Ts D^2 |U|^2
 * sn / norm is sin 2d alone, whatever the direction of U and whatever g (paper A's scalar e_q U_d
 * keeps a U_d U_q term). The model Gamma(i) is the motor's inverse incremental inductance: the
 * nominal 1/L_d, 1/L_q, or a fit of a flux map (cross-saturation: Gamma_dq odd in i_q). */
#ifndef RIPPLE_ERR_H
#define RIPPLE_ERR_H

#include <stdint.h>

/* Gamma(i_d, i_q) in 1/H:  g_dd = a0 + a1 i_d + a2 i_d^2 + a3 i_q^2
 *                          g_qq = b0 + b1 i_d + b2 i_d^2 + b3 i_q^2
 *                          g_dq = i_q (c0 + c1 i_d) */
/* Or a table of Gamma over a regular (i_d, i_q) grid, bilinear inside, clamped to the edges
 * (from the motor's flux map: the inverse of its incremental inductance matrix). */
#define RERR_TAB_MAX 400 /* nodes */
typedef struct {
    uint16_t nd, nq;    /* nodes along i_d and i_q (0: no table) */
    float id0_a, iq0_a; /* first node */
    float inv_did, inv_diq;
    float g[RERR_TAB_MAX][4]; /* g_dd, g_qq, g_dq, g_qd at node k * nd + j */
} rerr_tab_t;

typedef struct {
    float a0, a1, a2, a3;
    float b0, b1, b2, b3;
    float c0, c1;
    const rerr_tab_t *tab; /* NULL: the polynomial above */
} rerr_gamma_t;

typedef struct {
    float g_dd, g_qq, g_dq, g_qd; /* 1/H; g_dq: d row, q column (a measured map is not exactly
                                     symmetric: the antisymmetric part a J turns with the frame,
                                     R a J R^T = a J, so it only has to be in the prediction) */
} rerr_g_t;

typedef struct {
    float e_d_a, e_q_a; /* prediction error of the current change, estimated frame */
    float u_d_v, u_q_v; /* voltage across the inductances U, estimated frame */
    rerr_g_t g;         /* the model's Gamma at the operating point */
} rerr_in_t;

typedef struct {
    float sn;   /* Ts D^2 |U|^2 sin 2d, A V / H (times ts_s) */
    float cn;   /* Ts D^2 |U|^2 (cos 2d - 1) */
    float norm; /* Ts D^2 |U|^2 */
} rerr_out_t;

void rerr_gamma_linear(rerr_gamma_t *m, float l_d_h, float l_q_h);
void rerr_gamma_at(const rerr_gamma_t *m, float i_d_a, float i_q_a, rerr_g_t *g);
void rerr_eval(const rerr_in_t *in, float ts_s, rerr_out_t *out);

#endif
