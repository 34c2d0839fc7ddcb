/* Window averager for the steady-state identification (paper A (6)), C28x-safe.
 *
 * FCS-MPC applies one full inverter vector per period, so within a period L di/dt is of the order
 * of the applied voltage (hundreds of volts) and the steady-state equations (6) do not hold sample
 * by sample. This object integrates the dq model exactly over a window of n control periods:
 *   mean(u_d) = R mean(i_d) + L_d (i_d(end) - i_d(start))/T - L_q mean(w i_q)
 *   mean(u_q) = R mean(i_q) + L_q (i_q(end) - i_q(start))/T + L_d mean(w i_d) + psi_f mean(w)
 * (voltages: the period averages over [k, k+1); currents: trapezoidal means of the samples, exact
 * for the piecewise-linear ripple of FCS). The (end - start)/T terms are the residual di/dt; the
 * estimators move them to the target side with their current inductance estimates.
 * Call idw_step once per control period with the sample i(k) and the voltage of [k, k+1). */
#ifndef ID_WINDOW_H
#define ID_WINDOW_H

#include <stdint.h>
#include <stdbool.h>

/* One regression sample: window means (SI units). */
typedef struct {
    float t_window_s;                   /* window length T */
    float u_d_v, u_q_v;                 /* mean period-average voltages */
    float i_d_a, i_q_a;                 /* trapezoidal mean currents */
    float omega_e_rad_s;                /* mean electrical speed */
    float w_i_d_a_rad_s, w_i_q_a_rad_s; /* means of w i_d, w i_q */
    float di_d_a_s, di_q_a_s;           /* (i(end) - i(start)) / T */
} id_sample_t;

typedef struct {
    uint16_t n_periods; /* periods per window (>= 2) */
    float ts_s;         /* control period */
} idw_cfg_t;

typedef struct {
    float i_d_a, i_q_a;  /* sampled at k */
    float u_d_v, u_q_v;  /* period-average voltage over [k, k+1) (mpcc_out u_d_avg_v/u_q_avg_v) */
    float omega_e_rad_s; /* at k */
} idw_in_t;

typedef struct {
    idw_cfg_t cfg;
    uint16_t count;
    bool started;
    float s_ud, s_uq, s_id, s_iq, s_w, s_wid, s_wiq;
    float id0, iq0, w0, wid0, wiq0;
} idw_t;

void idw_init(idw_t *w, const idw_cfg_t *cfg);
void idw_reset(idw_t *w); /* discard the running window (PWM off, mode change) */
/* Adds period k; returns true (and fills *out) when a window closed at this sample. */
bool idw_step(idw_t *w, const idw_in_t *in, id_sample_t *out);

#endif
