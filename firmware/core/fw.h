/* The firmware application: protocol handler, profile executor, speed and current control,
 * faults, heartbeat, telemetry and capture. One object; the control period is a pipeline of
 * stages (docs/architecture.md): measure -> angle slot -> references -> current-control slot ->
 * estimators (ident_t) -> telemetry and the period's events. The board calls
 *   fw_rx_octet()  for every octet the UART received,
 *   fw_isr()       once per control period with the sampled measurements,
 *   fw_tx_pop()    to drain octets into the UART at the link rate.
 * and reads what it needs through the accessors below (never fw_t's fields).
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
#include "cc_slot.h"
#include "angle_slot.h"
#include "speed_pi.h"
#include "mtpa.h"
#include "enc_angle.h"
#include "dither.h"
#include "ident.h"
#include "evq.h"
#include "comm.h"

#define FW_VERSION_MAJOR 0u
#define FW_VERSION_MINOR 1u
#define FW_VERSION_PATCH 0u

typedef struct {
    uint16_t board;    /* PROTO_BOARD_* */
    uint16_t can_node; /* CAN node ID 0..15 (docs/can.md) */
} fw_cfg_t;

/* Board hook for messages the core does not know (the sim board's sim-only h2d messages):
 * returns an ack status (PROTO_ACK_STATUS_*). Set with fw_set_board_hook after fw_init. */
typedef uint16_t (*fw_board_msg_fn)(void *ctx, uint16_t msg_id, const uint16_t *payload,
                                    uint16_t n);

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

/* The link to the host: serial frames or CAN (docs/can.md). */
typedef struct {
    frame_parser_t rx;
    txq_t tx;
    uint16_t tx_seq;
    uint32_t rx_frames;
    uint32_t rx_bad;
    uint16_t frame_buf[2u * PROTO_MAX_PAYLOAD + 16u];
    uint16_t payload_buf[PROTO_MAX_PAYLOAD + 4u];
    can_link_t can;
    uint16_t link; /* FW_LINK_x: where replies go, the link of the last hello */
} fw_link_t;

/* The quick stop: speed reference ramp to zero, then PWM off. */
typedef struct {
    ramp_t ramp;
    uint32_t ticks;      /* periods since the stop began */
    uint32_t hold_ticks; /* periods of the present window at zero reference */
    float hold_sum_rpm;  /* the speed summed over them */
} fw_stop_t;

/* The telemetry streams' phases: tick % div for the fast, params, status and estimator frames,
 * set at a run's start and carried from period to period instead of a division each (fw_msg.c). */
enum {
    FW_TEL_FAST = 0,
    FW_TEL_PARAMS,
    FW_TEL_STATUS,
    FW_TEL_EST,
    FW_TEL_N
};
typedef struct {
    uint16_t div[FW_TEL_N]; /* the dividers they were taken with */
    uint16_t ph[FW_TEL_N];  /* tick % div[k] (0 for a stream that is off) */
    uint16_t at[FW_TEL_N];  /* the phase a frame goes out at, % div[k] (fast, status, est) */
    /* the dq voltage summed over the periods since the last fast frame, which carries its mean:
     * one period's FCS vector, sampled one period in div, would alias the switching */
    float u_d_sum_v, u_q_sum_v;
    uint16_t u_n;
} fw_tel_phase_t;

typedef struct {
    fw_cfg_t cfg;
    fw_motor_t motor;
    fw_limits_t limits;
    proto_config_ctrl_t ctrl;
    bool have_motor, have_ctrl;

    uint16_t state;        /* PROTO_STATE_* */
    uint16_t faults;       /* PROTO_FAULT_* bits */
    uint16_t stop_reason;  /* arg of the stopped event (PROTO_STOP_REASON_*) */
    uint32_t stop_at_tick; /* stop_at: the run stops (host_stop) at this tick; 0: never */
    uint32_t tick;         /* control periods since start */
    uint32_t isr_count;    /* free-running */
    uint32_t hb_isr;       /* isr_count at the last heartbeat */
    bool hb_lost;

    /* the pipeline's stages */
    profile_exec_t prof; /* references */
    ident_seg_t seg;     /* the running segment as the identification sees it */
    enc_t enc;           /* measure: the encoder (truth), when fitted */
    enc_out_t enc_out;
    angle_t angle;   /* angle slot */
    angle_out_t est; /* its occupant's output (an estimator's, or the encoder's) */
    angle_out_t ang; /* what the control uses: est, or the encoder in an angle_encoder segment */
    bool seg_angle_encoder; /* the running segment closes the loop on the encoder */
    uint32_t unlock_ticks;  /* periods the estimator in the loop has been out of lock */
    speed_pi_t spi;
    float i_s_ref_a;
    float i_d_base_a; /* d-current reference before the excitation */
    uint16_t speed_div_count;
    dither_t dither;
    cc_t cc;          /* current-control slot */
    cc_cfg_t cc_cfg;  /* its configuration (a segment may hand the slot over: cc_slot.h) */
    uint16_t cc_want; /* CC_KIND_* the running segment asks for */
    float u_d_mean_v, u_q_mean_v; /* cc_out's dq voltage low-passed over FW_CC_MEAN_TAU_S */
    cc_out_t cc_out;
    ident_t ident; /* estimators */
    /* the sensorless estimator's configuration (config_sensorless, gamma_node; docs/sensorless.md) */
    proto_config_sensorless_t snl_msg;
    bool have_snl;
    uint16_t gamma_nodes; /* nodes received since the last config_sensorless */
    rerr_tab_t gamma_tab;
    snl_cfg_t snl_cfg;
    capture_t cap;
    fw_stop_t stop;
    fw_signals_t sig; /* telemetry */
    evq_t events;     /* raised during the period, sent at its end */
    bool status_due;  /* a status frame follows the period's events */
    fw_tel_phase_t tel;

    /* commissioning (comm.h): the sequence runs in a `commission` segment */
    proto_config_calib_t calib; /* current-sensor calibration (all 0: none) */
    bool have_calib;
    proto_config_commission_t comm_cfg;
    bool commissioning; /* the running segment is a commission segment */
    comm_t comm;

    fw_board_msg_fn board_msg;
    void *board_ctx;
    fw_link_t link;
} fw_t;

void fw_init(fw_t *f, const fw_cfg_t *cfg);
void fw_rx_octet(fw_t *f, uint16_t octet);
void fw_isr(fw_t *f, const fw_meas_t *m, fw_cmd_t *cmd);
bool fw_tx_pop(fw_t *f, uint16_t *octet);
uint16_t fw_tx_pop_n(fw_t *f, uint16_t *out, uint16_t max);
/* Queue a frame from the board (e.g. the sim board's truth frames) on the same link. */
bool fw_send(fw_t *f, uint16_t msg_id, const uint16_t *payload, uint16_t n);
bool fw_active(const fw_t *f); /* running or stopping: the board must run the control ISR */
/* CAN: a received frame (data: dlc octets), and the next frame for the controller to send. */
#define FW_LINK_SERIAL 0u
#define FW_LINK_CAN    1u
void fw_can_rx(fw_t *f, uint16_t id, const uint16_t *data, uint16_t dlc);
void fw_set_board_hook(fw_t *f, fw_board_msg_fn fn, void *ctx);

/* Accessors for boards. */
uint32_t fw_tick(const fw_t *f);                 /* control periods since the run started */
uint32_t fw_isr_count(const fw_t *f);            /* control periods since fw_init */
uint32_t fw_heartbeat_isr(const fw_t *f);        /* fw_isr_count at the last heartbeat */
uint16_t fw_state(const fw_t *f);                /* PROTO_STATE_* */
uint16_t fw_segment(const fw_t *f, bool *begun); /* running segment; *begun: the profile started */
const proto_config_ctrl_t *fw_ctrl(const fw_t *f); /* the accepted config_ctrl, NULL before one */
uint32_t fw_tx_dropped(const fw_t *f);             /* messages the link could not queue */
uint16_t fw_tx_level(const fw_t *f);               /* octets queued for the UART */
uint16_t fw_can_tx_level(const fw_t *f);           /* CAN frames queued for the controller */
can_link_t *fw_can(fw_t *f); /* the CAN link's transmit side (the board's controller) */

#endif
