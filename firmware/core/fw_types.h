/* Shared SI-unit structs between the firmware core and its boards (F28335 or the emulator's sim board).
 * C28x-safe: no 8/64-bit integers, no double. */
#ifndef FW_TYPES_H
#define FW_TYPES_H

#include <stdint.h>
#include <stdbool.h>

#define FW_PI_F     3.14159265358979f
#define FW_TWO_PI_F 6.28318530717959f

/* Motor parameters as the firmware knows them (from the motor file via config_motor). */
typedef struct {
    uint16_t pole_pairs;
    float r_s_ohm;
    float l_d_h;
    float l_q_h;
    float psi_f_wb;
    float j_kgm2;
    float i_max_a;       /* current reference limit (magnitude) */
    float speed_max_rpm; /* speed reference limit */
} fw_motor_t;

/* What the board measured at the start of a control period (the ADC sample instant). */
typedef struct {
    float i_a_a;
    float i_b_a;
    float i_c_a;
    float v_dc_v;
    uint32_t enc_count; /* incremental encoder count, 0 .. enc_counts-1 per mechanical turn */
} fw_meas_t;

/* What the core asks the board to do for the next control period: forced switch states for the
 * whole period (finite-control-set control, FW_CMD_STATES) or three duties that the board's
 * compare-based PWM modulates with its dead band (FW_CMD_DUTIES). */
#define FW_CMD_STATES 0u
#define FW_CMD_DUTIES 1u

typedef struct {
    uint16_t mode; /* FW_CMD_STATES or FW_CMD_DUTIES */
    uint16_t s_a;  /* FW_CMD_STATES: upper switch of leg a on (1) or off (0) */
    uint16_t s_b;
    uint16_t s_c;
    float duty_a; /* FW_CMD_DUTIES: upper switch of leg a on for this fraction, [0, 1] */
    float duty_b;
    float duty_c;
    bool pwm_on;   /* false: all six switches off (safe state) */
    float load_nm; /* load torque the profile asks the rig's load machine for */
} fw_cmd_t;

/* dq quantities in the rotor frame. */
typedef struct {
    float d;
    float q;
} fw_dq_t;

#endif
