/* The telemetry schedule: fast frames go out at every tick that is a multiple of fast_div, status
 * frames at their phase of status_div, from the first tick of a run to the last, and a second run
 * with other dividers follows its own (the phases are carried from period to period, fw_msg.c). */
#include <string.h>

#include "check.h"
#include "frame.h"
#include "fw.h"
#include "proto_gen.h"

static fw_t fw; /* large: off the stack */
static frame_parser_t host_rx;
static uint16_t payload[PROTO_MAX_PAYLOAD + 4u];
static uint16_t wire[2u * PROTO_MAX_PAYLOAD + 16u];

#define MAX_SEEN 4096u
static uint32_t fast_ticks[MAX_SEEN], status_ticks[MAX_SEEN];
static uint32_t n_fast, n_status;

static uint16_t ack_id, ack_status;

static void collect(void)
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
        } else if (host_rx.msg_id == PROTO_ID_TELEM_FAST && n_fast < MAX_SEEN) {
            proto_telem_fast_t t;
            if (proto_telem_fast_unpack(&t, host_rx.payload, host_rx.payload_len)) {
                fast_ticks[n_fast++] = t.tick;
            }
        } else if (host_rx.msg_id == PROTO_ID_STATUS && n_status < MAX_SEEN) {
            proto_status_t s;
            if (proto_status_unpack(&s, host_rx.payload, host_rx.payload_len)) {
                status_ticks[n_status++] = s.tick;
            }
        }
    }
}

/* Sends one message as the host would; the status of the device's ack (0xFFFF: none). */
static uint16_t send(uint16_t id, uint16_t n)
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
    collect();
    return ack_id == id ? ack_status : 0xFFFFu;
}

static void configure(uint16_t fast_div, uint16_t status_div)
{
    proto_config_motor_t m;
    proto_config_ctrl_t c;
    proto_profile_segment_t s;
    proto_profile_clear_t clr;
    memset(&clr, 0, sizeof clr);
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
    CHECK(send(PROTO_ID_CONFIG_MOTOR, proto_config_motor_pack(&m, payload)) == PROTO_ACK_STATUS_OK,
          "motor");
    memset(&c, 0, sizeof c);
    c.ts_s = 50e-6f;
    c.rho = 1.0f;
    c.speed_kp_a_per_rad_s = 0.5f;
    c.speed_ki_a_per_rad = 20.0f;
    c.speed_div = 20u;
    c.heartbeat_timeout_s = 0.5f;
    c.fast_div = fast_div;
    c.status_div = status_div;
    c.enc_counts = 10000u;
    c.speed_obs_bw_rad_s = 500.0f;
    c.capture_pre = 16u;
    c.id_window = 20u;
    c.pred_scale_l_d = 1.0f;
    c.pred_scale_l_q = 1.0f;
    c.pred_scale_psi_f = 1.0f;
    c.pred_scale_r_s = 1.0f;
    CHECK(send(PROTO_ID_CONFIG_CTRL, proto_config_ctrl_pack(&c, payload)) == PROTO_ACK_STATUS_OK,
          "ctrl");
    clr.n_segments = 1u;
    CHECK(send(PROTO_ID_PROFILE_CLEAR, proto_profile_clear_pack(&clr, payload)) ==
              PROTO_ACK_STATUS_OK,
          "profile clear");
    memset(&s, 0, sizeof s);
    s.duration_s = 0.02f; /* 400 periods, then the stop */
    s.speed_rpm = 0.0f;
    CHECK(send(PROTO_ID_PROFILE_SEGMENT, proto_profile_segment_pack(&s, payload)) ==
              PROTO_ACK_STATUS_OK,
          "segment");
}

/* One run from start to rest; returns the number of periods it lasted. */
static uint32_t run(void)
{
    fw_meas_t meas = { 0.0f, 0.0f, 0.0f, 540.0f, 0u };
    fw_cmd_t cmd;
    proto_start_t st = { 0u };
    uint32_t k = 0u;
    n_fast = 0u;
    n_status = 0u;
    CHECK(send(PROTO_ID_START, proto_start_pack(&st, payload)) == PROTO_ACK_STATUS_OK, "start");
    while (fw_active(&fw) && k < 20000u) {
        fw_isr(&fw, &meas, &cmd);
        collect();
        k++;
    }
    return k;
}

/* every frame on its phase, none missing between the first and the last tick of the run */
static void check_schedule(uint32_t periods, uint16_t fast_div, uint16_t status_div,
                           uint32_t status_phase)
{
    uint32_t i, t, bad = 0u;
    CHECK(periods > 400u && periods < 20000u, "the run ends");
    CHECK(n_fast == (periods + fast_div - 1u) / fast_div, "one fast frame per fast_div periods");
    for (i = 0u; i < n_fast; i++) {
        bad += fast_ticks[i] != i * fast_div ? 1u : 0u;
    }
    CHECK(bad == 0u, "fast frames at the multiples of fast_div, from tick 0");
    /* status frames also follow the period's events: each scheduled tick has one */
    for (t = status_phase, bad = 0u; t < periods; t += status_div) {
        bool seen = false;
        for (i = 0u; i < n_status && !seen; i++) {
            seen = status_ticks[i] == t;
        }
        bad += seen ? 0u : 1u;
    }
    CHECK(bad == 0u, "a status frame at every tick of its phase");
}

int main(void)
{
    fw_cfg_t cfg = { PROTO_BOARD_EMULATOR, 1u };
    uint32_t periods;
    fw_init(&fw, &cfg);
    frame_parser_init(&host_rx);

    configure(10u, 200u);
    periods = run();
    check_schedule(periods, 10u, 200u, 5u); /* status phase: after the params slots (fw_msg.c) */

    /* the next run with other dividers: the phases start again from its tick 0 */
    configure(7u, 50u);
    periods = run();
    check_schedule(periods, 7u, 50u, 5u);
    return CHECK_DONE();
}
