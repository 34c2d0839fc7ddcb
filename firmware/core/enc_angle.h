/* Incremental-encoder occupant of the angle/speed slot (C28x-safe).
 *   theta_m = count 2pi/counts,  theta_e = wrap(p theta_m + offset)   (the encoder's raw reading)
 * Speed: a type-2 tracking observer (PLL / alpha-beta tracker) on the unwrapped count, run every
 * control period:
 *   x^(k|k-1) = x^(k-1) + ts w^(k-1);   e = count - x^(k|k-1)   (wrapped to +-counts/2)
 *   x^(k) = x^(k|k-1) + k1 ts e;        w^(k) = w^(k-1) + k2 ts e
 *   k1 = 2 zeta bw, k2 = bw^2, zeta = 1/sqrt(2).
 * The speed output is the observer's speed state w^, whose response to the true speed is the
 * second-order low-pass bw^2 / (s^2 + 2 zeta bw s + bw^2): -3 dB at bw, 2nd-order roll-off of the
 * count quantisation. The observer angle is kept as an integer count plus a float fraction so it
 * does not lose resolution over long runs. See docs/control.md for the bandwidth choice. */
#ifndef ENC_ANGLE_H
#define ENC_ANGLE_H

#include <stdint.h>
#include <stdbool.h>
#include "fw_types.h"

#define ENC_ZETA_F 0.70710678f
/* recommended for paper A's drive (10000 counts, 1 kHz speed loop) */
#define ENC_BW_DEFAULT_RAD_S 1000.0f

typedef struct {
    uint32_t counts; /* counts per mechanical turn (4 x lines); >= 4 */
    uint16_t pole_pairs;
    float offset_e_rad; /* electrical angle at count 0 */
    float bw_rad_s;     /* observer bandwidth (speed -3 dB) */
    float ts_s;         /* call period (the control period) */
} enc_cfg_t;

typedef struct {
    float theta_e_rad;   /* raw-count electrical angle, [0, 2pi) */
    float theta_m_rad;   /* raw-count mechanical angle, [0, 2pi) */
    float omega_m_rad_s; /* observer speed */
    float omega_e_rad_s;
    float speed_rpm;
    /* Added outputs */
    float theta_e_obs_rad; /* observer electrical angle, [0, 2pi): smoother, lags only by the
                               observer's angle error (zero at constant speed) */
    float err_counts;      /* observer innovation (count - prediction) */
} enc_out_t;

typedef struct {
    enc_cfg_t cfg;
    float rad_per_count;
    float k1_ts, k2_ts; /* observer gains times ts */
    uint32_t n_obs;     /* observer angle, integer counts, 0 .. counts-1 */
    float f_obs;        /* observer angle, fractional counts, [0, 1) */
    float w_cps;        /* observer speed, counts/s */
    bool int_elec;      /* counts * pole_pairs fits 32 bits: exact integer electrical angle */
} enc_t;

void enc_init(enc_t *e, const enc_cfg_t *cfg);
void enc_step(enc_t *e, uint32_t count, enc_out_t *out);
/* Restart the observer at this count with zero speed. */
void enc_reset(enc_t *e, uint32_t count);

#endif
