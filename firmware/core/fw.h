/* The firmware application: protocol handler, profile executor, speed and current control,
 * faults, heartbeat, telemetry and capture. One object; the board calls
 *   fw_rx_octet()  for every octet the UART received,
 *   fw_isr()       once per control period with the sampled measurements,
 *   fw_tx_pop()    to drain octets into the UART at the link rate.
 * Nothing here reads a clock: time is the count of control periods. */
#ifndef FW_H
#define FW_H

#include <stdint.h>
#include <stdbool.h>

#include "fw_types.h"
#include "frame.h"
#include "proto_gen.h"
#include "txq.h"
#include "capture.h"
#include "profile_exec.h"
#include "mpcc.h"
#include "speed_pi.h"
#include "mtpa.h"
#include "enc_angle.h"
#include "dither.h"

#define FW_VERSION_MAJOR 0u
#define FW_VERSION_MINOR 1u
#define FW_VERSION_PATCH 0u

#define FW_BOARD_SIM 0u
#define FW_BOARD_F28335 1u

typedef struct {
    uint16_t board;          /* FW_BOARD_SIM or FW_BOARD_F28335 */
} fw_cfg_t;

/* Fault limits beyond the motor struct (config_motor). */
typedef struct {
    float i_trip_a;
    float speed_trip_rpm;
    float v_dc_min_v;
    float v_dc_max_v;
} fw_limits_t;

/* The last control period's signals, for telemetry and the board. */
typedef struct {
    float speed_ref_rpm, speed_rpm, speed_est_rpm;
    float theta_e_rad, theta_e_est_rad, omega_e_rad_s;
    float i_d_a, i_q_a, i_d_ref_a, i_q_ref_a, u_d_v, u_q_v, load_nm, v_dc_v;
} fw_signals_t;

typedef struct {
    fw_cfg_t cfg;
    fw_motor_t motor;
    fw_limits_t limits;
    proto_config_ctrl_t ctrl;
    bool have_motor, have_ctrl;

    uint16_t state;          /* PROTO_STATE_* */
    uint16_t faults;         /* PROTO_FAULT_* bits */
    uint16_t stop_reason;    /* arg of the stopped event */
    uint32_t tick;           /* control periods since start */
    uint32_t isr_count;      /* free-running */
    uint32_t hb_isr;         /* isr_count at the last heartbeat */
    bool hb_lost;

    profile_exec_t prof;
    capture_t cap;
    mpcc_t mpcc;
    speed_pi_t spi;
    enc_t enc;
    enc_out_t enc_out;
    dither_t dither;
    float i_s_ref_a;
    float stop_ref_rpm;
    uint32_t stop_ticks;
    uint32_t stop_hold_ticks;
    uint16_t speed_div_count;

    fw_signals_t sig;

    /* link */
    frame_parser_t rx;
    txq_t tx;
    uint16_t tx_seq;
    uint32_t rx_frames;
    uint32_t rx_bad;
    uint16_t frame_buf[2u * PROTO_MAX_PAYLOAD + 16u];
    uint16_t payload_buf[PROTO_MAX_PAYLOAD + 4u];
} fw_t;

void fw_init(fw_t *f, const fw_cfg_t *cfg);
void fw_rx_octet(fw_t *f, uint16_t octet);
void fw_isr(fw_t *f, const fw_meas_t *m, fw_cmd_t *cmd);
bool fw_tx_pop(fw_t *f, uint16_t *octet);
uint16_t fw_tx_pop_n(fw_t *f, uint16_t *out, uint16_t max);
/* Queue a frame from the board (e.g. the sim board's truth frames) on the same link. */
bool fw_send(fw_t *f, uint16_t msg_id, const uint16_t *payload, uint16_t n);
bool fw_active(const fw_t *f);   /* running or stopping: the board must run the control ISR */

#endif
