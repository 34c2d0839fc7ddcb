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
 * The window's mean speed is its angle step over T (the mean of w over the window exactly; the
 * speed estimate lags whenever the speed loop accelerates, and psi_f w turns 1 % of lag into
 * 0.7 V on u_q at 1000 r/min); mean(w i_d), mean(w i_q) are shifted by the same correction.
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
    uint16_t n_periods; /* periods per window (>= 2); with sector_sync the least */
    float ts_s;         /* control period */
    /* sector_sync: a window ends at the period boundary nearest to a whole number of 60 degree
     * electrical sectors (at least n_periods, at most IDW_SYNC_MAX x n_periods): the sixth
     * harmonic in dq of the flux harmonics (5th, 7th), of the inverter's distortion and of
     * cogging at a multiple of 6 per electrical turn averages out of each window. */
    bool sector_sync;
} idw_cfg_t;

#define IDW_SYNC_MAX 8u

typedef struct {
    float i_d_a, i_q_a;  /* sampled at k */
    float u_d_v, u_q_v;  /* period-average voltage over [k, k+1) (mpcc_out u_d_avg_v/u_q_avg_v) */
    float omega_e_rad_s; /* at k */
    float theta_e_rad;   /* at k: the window's mean speed is its angle step over T */
} idw_in_t;

typedef struct {
    idw_cfg_t cfg;
    uint16_t count;
    bool started;
    float s_ud, s_uq, s_id, s_iq, s_w, s_wid, s_wiq;
    float id0, iq0, w0, wid0, wiq0;
    float ang_rad;    /* electrical angle swept by the running window (unwrapped) */
    float th_prev;    /* angle of the last sample */
    float target_rad; /* sector_sync: the angle to end at (0: not chosen yet) */
} idw_t;

void idw_init(idw_t *w, const idw_cfg_t *cfg);
void idw_reset(idw_t *w); /* discard the running window (PWM off, mode change) */
/* Adds period k; returns true (and fills *out) when a window closed at this sample. */
bool idw_step(idw_t *w, const idw_in_t *in, id_sample_t *out);

#endif
