/* A host for the firmware's unit tests: the firmware object, sending a message as the host would
 * (the status of its ack), the frames the device sends back (host_on_frame), a sane motor and
 * control configuration, and a profile of one segment to run. */
#ifndef FW_HOST_H
#define FW_HOST_H

#include <string.h>

#include "check.h"
#include "frame.h"
#include "fw.h"
#include "proto_gen.h"

static fw_t fw; /* large: off the stack */
static frame_parser_t host_rx;
static uint16_t payload[PROTO_MAX_PAYLOAD + 4u];
static uint16_t wire[2u * PROTO_MAX_PAYLOAD + 16u];
static uint16_t ack_id, ack_status;
static void (*host_on_frame)(const frame_parser_t *rx); /* every frame but acks (may be NULL) */

/* Reads what the device has sent. */
static inline void host_collect(void)
{
    uint16_t octet;
    while (fw_tx_pop(&fw, &octet)) {
        if (frame_parser_push(&host_rx, octet) != FRAME_OK) {
            continue;
        }
        if (host_rx.msg_id == PROTO_ID_ACK) {
            proto_ack_t a;
            if (proto_ack_unpack(&a, host_rx.payload, host_rx.payload_len)) {
                ack_id = a.cmd_id;
                ack_status = a.status;
            }
        } else if (host_on_frame != NULL) {
            host_on_frame(&host_rx);
        }
    }
}

/* Sends one message as the host would; the status of the device's ack (0xFFFF: none). */
static inline uint16_t host_send(uint16_t id, uint16_t n)
{
    static uint16_t seq = 0u;
    uint16_t len =
        frame_encode(id, seq, payload, n, wire, (uint16_t)(sizeof wire / sizeof wire[0]));
    uint16_t i;
    seq = (uint16_t)((seq + 1u) & 0xFFu);
    ack_status = 0xFFFFu;
    for (i = 0u; i < len; i++) {
        fw_rx_octet(&fw, wire[i]);
    }
    host_collect();
    return ack_id == id ? ack_status : 0xFFFFu;
}

/* A sane motor: paper A's 4-pole-pair IPMSM with its limits. */
static inline proto_config_motor_t host_good_motor(void)
{
    proto_config_motor_t m;
    memset(&m, 0, sizeof m);
    m.pole_pairs = 4u;
    m.r_s_ohm = 0.9f;
    m.l_d_h = 5e-3f;
    m.l_q_h = 12e-3f;
    m.psi_f_wb = 0.18f;
    m.j_kgm2 = 3.6e-3f;
    m.i_max_a = 20.0f;
    m.speed_max_rpm = 1500.0f;
    m.i_trip_a = 30.0f;
    m.speed_trip_rpm = 1800.0f;
    m.v_dc_min_v = 400.0f;
    m.v_dc_max_v = 700.0f;
    return m;
}

/* A sane control configuration: 20 kHz, fast telemetry every 10 periods, status every 2000. */
static inline proto_config_ctrl_t host_good_ctrl(void)
{
    proto_config_ctrl_t c;
    memset(&c, 0, sizeof c);
    c.ts_s = 50e-6f;
    c.rho = 1.0f;
    c.speed_kp_a_per_rad_s = 0.5f;
    c.speed_ki_a_per_rad = 20.0f;
    c.speed_div = 20u;
    c.heartbeat_timeout_s = 0.5f;
    c.fast_div = 10u;
    c.status_div = 2000u;
    c.enc_counts = 10000u;
    c.speed_obs_bw_rad_s = 500.0f;
    c.capture_pre = 16u;
    c.id_window = 20u;
    c.pred_scale_l_d = 1.0f;
    c.pred_scale_l_q = 1.0f;
    c.pred_scale_psi_f = 1.0f;
    c.pred_scale_r_s = 1.0f;
    return c;
}

/* The sane motor, this control configuration and a profile of one segment. */
static inline void host_configure(const proto_config_ctrl_t *c, const proto_profile_segment_t *s)
{
    proto_config_motor_t m = host_good_motor();
    proto_profile_clear_t clr;
    CHECK(host_send(PROTO_ID_CONFIG_MOTOR, proto_config_motor_pack(&m, payload)) ==
              PROTO_ACK_STATUS_OK,
          "motor");
    CHECK(host_send(PROTO_ID_CONFIG_CTRL, proto_config_ctrl_pack(c, payload)) ==
              PROTO_ACK_STATUS_OK,
          "ctrl");
    memset(&clr, 0, sizeof clr);
    clr.n_segments = 1u;
    CHECK(host_send(PROTO_ID_PROFILE_CLEAR, proto_profile_clear_pack(&clr, payload)) ==
              PROTO_ACK_STATUS_OK,
          "profile clear");
    CHECK(host_send(PROTO_ID_PROFILE_SEGMENT, proto_profile_segment_pack(s, payload)) ==
              PROTO_ACK_STATUS_OK,
          "segment");
}

static inline void host_start(void)
{
    proto_start_t st = { 0u };
    CHECK(host_send(PROTO_ID_START, proto_start_pack(&st, payload)) == PROTO_ACK_STATUS_OK,
          "start");
}

#endif
