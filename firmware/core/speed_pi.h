/* Speed PI controller (C28x-safe), run at the speed-loop rate (1 kHz by default).
 * Input: mechanical speed in rad/s. Output: the stator current magnitude command i_s (A), signed
 * (+ = motoring forward), clamped to +-out_max_a.
 *   i_s = kp (b ref - meas) + I,   I += ki ts e   (e = ref - meas, set-point weight b = 1 by default)
 * Anti-windup: conditional integration (clamping). The integrator is not advanced when the
 * output is saturated and the error would push it further into saturation, and the integrator
 * itself is held within +-out_max_a. See docs/control.md. */
#ifndef SPEED_PI_H
#define SPEED_PI_H

#include <stdint.h>
#include <stdbool.h>

typedef struct {
    float kp_a_per_rad_s; /* A per (mechanical rad/s) */
    float ki_a_per_rad;   /* A per (mechanical rad/s) per s = A/rad */
    float ts_s;           /* speed-loop period */
    float out_max_a;      /* output clamp (the current limit) */
} speed_pi_cfg_t;

typedef struct {
    speed_pi_cfg_t cfg;
    float ref_weight; /* set-point weight b of the P term, kp (b ref - meas); 1 after init
                               (plain PI), see speed_pi_set_ref_weight */
    float integ_a;    /* integrator state (A) */
    float out_a;      /* last output (A) */
    bool saturated;   /* last output was clamped */
} speed_pi_t;

void speed_pi_init(speed_pi_t *p, const speed_pi_cfg_t *cfg);
float speed_pi_step(speed_pi_t *p, float ref_rad_s, float meas_rad_s);
/* Preload the integrator with out0_a (clamped): bumpless when the P term is zero, i.e. with
 * b = 1 and ref = meas, or at standstill with ref = 0 (the usual start). */
void speed_pi_reset(speed_pi_t *p, float out0_a);
/* Bumpless preset for any b: the next output is out0_a for these ref and meas. */
void speed_pi_preset(speed_pi_t *p, float out0_a, float ref_rad_s, float meas_rad_s);
/* Two-degree-of-freedom PI: the P term acts on b ref - meas (0 <= b <= 1). b < 1 lowers the
 * overshoot to reference steps; the load-disturbance response is unchanged. Default 1. */
void speed_pi_set_ref_weight(speed_pi_t *p, float b);
/* Change the clamp at run time (e.g. a derated current limit). */
void speed_pi_set_limit(speed_pi_t *p, float out_max_a);

/* Gains for a target crossover bw_rad_s of the speed loop J s w = kt i - T_L (ideal current loop):
 *   kp = J bw / kt,  ki = kp bw / 4  (PI zero a quarter of the crossover: ~76 deg phase margin
 *   before delays; closed-loop double pole at -bw/2). See docs/control.md. */
void speed_pi_design(float j_kgm2, float kt_nm_per_a, float bw_rad_s, float *kp, float *ki);

#endif
