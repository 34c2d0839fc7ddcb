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
#include "can_link.h"
#include "capture.h"
#include "profile_exec.h"
#include "mpcc.h"
#include "speed_pi.h"
#include "mtpa.h"
#include "enc_angle.h"
#include "dither.h"
#include "id_window.h"
#include "est_rls.h"
#include "est_adaline.h"
#include "est_nlms.h"
#include "r_inject.h"

#define FW_VERSION_MAJOR 0u
#define FW_VERSION_MINOR 1u
#define FW_VERSION_PATCH 0u

#define FW_BOARD_SIM 0u
#define FW_BOARD_F28335 1u

typedef struct {
    uint16_t board;          /* FW_BOARD_SIM or FW_BOARD_F28335 */
    uint16_t can_node;       /* CAN node ID 0..15 (docs/can.md) */
} fw_cfg_t;

/* Online identification: the three estimators, index = PROTO_ESTIMATOR_x - 1. */
#define FW_N_EST 3u
#define FW_EST_RLS 0u
#define FW_EST_ADALINE 1u
#define FW_EST_NLMS 2u
#define FW_R_SETTLE_FRAC 0.2f   /* identify_r: part of each current level skipped (settling) */
#define FW_ID_STEP_A 0.5f       /* identification: an i_d reference step above this skips the window */
#define FW_ID_STEP_HOLD 5u      /* ... and the windows of the next periods (the MPCC transient) */

/* Board hook for messages the core does not know (the sim board's sim-only h2d messages):
 * returns an ack status (PROTO_ACK_STATUS_*). Set with fw_set_board_hook after fw_init. */
typedef uint16_t (*fw_board_msg_fn)(void *ctx, uint16_t msg_id, const uint16_t *payload, uint16_t n);

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
    ramp_t stop_ramp;     /* quick-stop speed reference */
    uint32_t stop_ticks;
    uint32_t stop_hold_ticks;
    uint16_t speed_div_count;

    fw_signals_t sig;

    /* online identification (docs/identification.md) */
    idw_t idw;
    est_rls_t est_rls;
    est_adaline_t est_ada;
    est_nlms_t est_nlms;
    est_out_t est_out[FW_N_EST];
    rinj_t rinj;
    rinj_out_t rinj_out;
    bool have_injection;     /* the profile has an identify_r segment */
    bool r_identified;
    bool r_injecting;        /* an identify_r segment is running */
    float r_ident_ohm;
    bool pred_latched;       /* the chosen estimator converged once: it feeds the predictor */
    float i_d_base_a;        /* d-current reference before the excitation */
    float id_ref_prev_a;     /* identification: i_d reference of the previous period */
    bool idw_step_seen;      /* identification: the running window holds an i_d reference step */
    uint16_t id_step_hold;   /* identification: periods of current transient still to come */
    uint16_t seg_kind;
    uint16_t seg_flags;        /* PROFILE_FLAG_* of the running segment */
    float seg_inject_a, seg_inject_hz;
    uint32_t seg_tick, seg_ticks;
    float pred_r_s_ohm, pred_l_d_h, pred_l_q_h, pred_psi_f_wb;   /* what the predictor used last */

    /* board hook */
    fw_board_msg_fn board_msg;
    void *board_ctx;

    /* link */
    frame_parser_t rx;
    txq_t tx;
    uint16_t tx_seq;
    uint32_t rx_frames;
    uint32_t rx_bad;
    uint16_t frame_buf[2u * PROTO_MAX_PAYLOAD + 16u];
    uint16_t payload_buf[PROTO_MAX_PAYLOAD + 4u];
    can_link_t can;          /* CAN link (docs/can.md) */
    uint16_t link;           /* FW_LINK_x: where replies go, the link of the last hello */
} fw_t;

void fw_init(fw_t *f, const fw_cfg_t *cfg);
void fw_rx_octet(fw_t *f, uint16_t octet);
void fw_isr(fw_t *f, const fw_meas_t *m, fw_cmd_t *cmd);
bool fw_tx_pop(fw_t *f, uint16_t *octet);
uint16_t fw_tx_pop_n(fw_t *f, uint16_t *out, uint16_t max);
/* Queue a frame from the board (e.g. the sim board's truth frames) on the same link. */
bool fw_send(fw_t *f, uint16_t msg_id, const uint16_t *payload, uint16_t n);
bool fw_active(const fw_t *f);
/* CAN: a received frame (data: dlc octets), and the next frame for the controller to send. */
#define FW_LINK_SERIAL 0u
#define FW_LINK_CAN 1u
void fw_can_rx(fw_t *f, uint16_t id, const uint16_t *data, uint16_t dlc);
void fw_set_board_hook(fw_t *f, fw_board_msg_fn fn, void *ctx);   /* running or stopping: the board must run the control ISR */

#endif
