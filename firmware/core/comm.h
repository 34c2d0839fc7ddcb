/* Commissioning: a sequence of measurements that the firmware runs by itself in a `commission`
 * profile segment (docs/commissioning.md). Each step is a file of its own (comm_offset.c,
 * comm_align.c, comm_inverter.c, comm_rl.c, comm_spin.c); comm.c sequences them and holds what
 * they share: the calibrated measurement, a current controller in a given frame, the duty
 * output and the inverter model measured so far. A step validates its result and fails with a
 * reason (PROTO_COMMISSION_FAIL_*); the caller then switches the PWM off.
 * C28x-safe: no 8/64-bit integers, no double; time is the count of control periods. */
#ifndef COMM_H
#define COMM_H

#include <stdint.h>
#include <stdbool.h>

#include "fw_types.h"
#include "proto_gen.h"

#define COMM_N_STEPS   7u
#define COMM_STAIR_MAX 48u /* staircase levels: both directions, space-vector and clamped PWM */
#define COMM_RES_N     6u  /* values (and spreads) of one step's result */

#define COMM_RUNNING 0u
#define COMM_DONE    1u
#define COMM_FAILED  2u

typedef struct {
    uint16_t steps; /* bit k: run step k (PROTO_COMMISSION_STEP_*) */
    float i_test_a; /* largest test current */
    float spin_rpm; /* top speed of the psi_f spin */
    float ts_s;
    float v_dc_min_v, v_dc_max_v;
    fw_motor_t motor;   /* nominal values: plausibility ranges and controller gains */
    float i_dt_nom_a;   /* the motor file's inverter model (starting point) */
    float v_drop_nom_v; /* its device drop: the part of the plateau that does not scale with v_dc */
    uint32_t enc_counts; /* encoder counts per revolution (the count's floor: half a count) */
} comm_cfg_t;

typedef struct {
    float i_a_a, i_b_a, i_c_a; /* calibrated by the firmware's config_calib */
    float v_dc_v;
    float theta_enc_rad; /* encoder electrical angle (with the configured offset) */
    float omega_e_rad_s; /* encoder observer */
} comm_in_t;

typedef struct {
    bool pwm_on;
    float duty[3];
    /* for telemetry */
    float i_d_a, i_q_a, i_d_ref_a, i_q_ref_a, u_d_v, u_q_v, speed_ref_rpm;
} comm_out_t;

/* One step's result as sent to the host (proto commission_result). */
typedef struct {
    uint16_t step, status;
    float value[COMM_RES_N], spread[COMM_RES_N], ref[2];
} comm_result_t;

/* Running sums of a linear regression y = sum a_j x_j (n_x regressors, the last one 1). */
#define COMM_REG_N 4u
typedef struct {
    float sxx[COMM_REG_N][COMM_REG_N];
    float sxy[COMM_REG_N];
    uint32_t n;
} comm_reg_t;

typedef struct {
    comm_cfg_t cfg;
    uint16_t step;    /* the running step */
    uint16_t phase;   /* sub-state within the step */
    uint32_t t;       /* periods in this phase */
    uint32_t t_total; /* periods since the sequence started */
    uint16_t status;  /* COMM_RUNNING, _DONE, _FAILED */
    uint16_t fail_reason;
    bool step_started; /* the step's first period: raise commission_step */
    bool result_due;   /* res holds a result to send */
    comm_result_t res;

    /* calibration measured so far, applied to the samples of later steps */
    float off_a, off_b, off_c;
    float gerr_a, gerr_b, gerr_c;
    float enc_delta_rad; /* added to theta_enc_rad: the rotor's d axis */
    bool have_enc;
    float inv_v, inv_i_dt_a; /* inverter distortion plateau (per leg) and current band */
    float inv_vdc_v;         /* the DC voltage inv_v was measured at (its dead-time part scales) */
    float inv_drop_v;        /* its device-drop part (does not scale with v_dc) */
    bool have_inv;
    bool dpwm_lo; /* comm_voltage clamps the lowest leg to the lower rail (no edges in that leg) */
    float r_ohm;
    bool have_r;
    float l_d_h, l_q_h;

    /* this period's calibrated sample */
    float ia, ib, ic, v_dc;
    float th_rotor, c_rot, s_rot; /* rotor angle (have_enc) and its cos/sin */

    /* current controller (frame angle given each period) */
    float kp_d, ki_d, kp_q, ki_q, int_d, int_q;
    float u_d, u_q; /* last commanded dq voltage (in the controller's frame) */
    float
        adv_rad; /* the voltage's frame leads the current's by this (rotation during the PWM delay) */
    float u_hist[3];  /* commanded voltage on the tested axis, k, k-1, k-2 */
    float i_prev;     /* previous sample on the tested axis */
    float i_max_step; /* over-current limit of the running step */

    /* accumulators shared by the steps (reset at each phase that measures) */
    float acc[8];
    uint32_t acc_n;
    float blk[6][4]; /* block or point results */
    uint16_t n_blk;
    float sc_sum, ss_sum; /* circular mean (encoder) */
    float theta_unwrap, theta_last;
    float target_rad;
    /* staircase */
    float st_i[COMM_STAIR_MAX], st_u[COMM_STAIR_MAX], st_abc[COMM_STAIR_MAX][3];
    float st_th[COMM_STAIR_MAX], st_vdc[COMM_STAIR_MAX];
    float st_sw[COMM_STAIR_MAX][3]; /* share of the periods in which each leg switched */
    uint16_t st_n, st_k;
    comm_reg_t reg[2];
    /* spin */
    float spd_int, spd_ref_rpm, psi_pt[2];
} comm_t;

void comm_start(comm_t *c, const comm_cfg_t *cfg);
/* One control period; returns COMM_RUNNING, COMM_DONE or COMM_FAILED. */
uint16_t comm_step(comm_t *c, const comm_in_t *in, comm_out_t *out);
/* The host asked to stop: brake a spinning rotor with the commissioning's own controller, or
 * switch off at once at standstill; returns true once the PWM may go off. */
bool comm_brake(comm_t *c, const comm_in_t *in, comm_out_t *out);

/* ---- shared by the step files (comm.c) */
void comm_next_phase(comm_t *c);
void comm_fail(comm_t *c, uint16_t reason);
void comm_finish_step(comm_t *c); /* the step's result is in c->res: send it, go on */
void comm_acc_reset(comm_t *c);
float comm_dt(const comm_t *c, float seconds_f); /* seconds -> periods (as float) */
bool comm_elapsed(const comm_t *c, float seconds_f);
/* Current control in the frame at (cos, sin) to (i_d_ref, i_q_ref); writes duties. Returns the
 * measured (i_d, i_q) in that frame through the pointers. */
void comm_current(comm_t *c, float cs, float sn, float i_d_ref, float i_q_ref, float *i_d,
                  float *i_q, comm_out_t *out);
/* A voltage (u_d, u_q) in the frame at (cos, sin) as duties. */
void comm_voltage(comm_t *c, float cs, float sn, float u_d, float u_q, comm_out_t *out);
/* The measured inverter model's distortion in the frame at (cos, sin) for phase currents i[3]:
 * what the inverter adds to the commanded voltage (negative along the current). */
void comm_inv_dist(const comm_t *c, const float i_abc[3], float cs, float sn, float *d, float *q);
float comm_smooth_sign(float i, float i_dt);
/* the plateau at the DC voltage v_dc: the dead-time part scales with it, the drop does not */
float comm_inv_plateau(const comm_t *c, float v_dc);
bool comm_over_current(comm_t *c);
void comm_reg_reset(comm_reg_t *r);
void comm_reg_add(comm_reg_t *r, const float x[COMM_REG_N], float y);
/* Least squares on the first n regressors (n <= COMM_REG_N; the others' sums are ignored). */
bool comm_reg_solve(const comm_reg_t *r, uint16_t n, float a[COMM_REG_N]);

/* the steps */
void comm_offset_step(comm_t *c, comm_out_t *out);
void comm_vdc_step(comm_t *c, comm_out_t *out);
void comm_align_step(comm_t *c, const comm_in_t *in, comm_out_t *out);
void comm_inverter_step(comm_t *c, comm_out_t *out);
void comm_r_step(comm_t *c, comm_out_t *out);
void comm_l_step(comm_t *c, comm_out_t *out);
void comm_spin_step(comm_t *c, const comm_in_t *in, comm_out_t *out);

#endif
