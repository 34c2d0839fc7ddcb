/* The firmware refuses settings that would switch its own protection off (non-finite values,
 * an unbounded heartbeat timeout, trip limits beyond the hard ceilings, durations whose tick
 * count would overflow), and a non-finite measurement trips it. */
#include <math.h>
#include <string.h>

#include "check.h"
#include "frame.h"
#include "fw.h"
#include "proto_gen.h"

static fw_t fw; /* large: off the stack */
static frame_parser_t host_rx;
static uint16_t payload[PROTO_MAX_PAYLOAD + 4u];
static uint16_t wire[2u * PROTO_MAX_PAYLOAD + 16u];

/* Sends one message as the host would, returns the status of the device's ack (0xFFFF: none). */
static uint16_t send(uint16_t id, uint16_t n)
{
    static uint16_t seq = 0u;
    uint16_t len =
        frame_encode(id, seq, payload, n, wire, (uint16_t)(sizeof wire / sizeof wire[0]));
    uint16_t i, octet, status = 0xFFFFu;
    seq = (uint16_t)((seq + 1u) & 0xFFu);
    for (i = 0u; i < len; i++) {
        fw_rx_octet(&fw, wire[i]);
    }
    while (fw_tx_pop(&fw, &octet)) {
        if (frame_parser_push(&host_rx, octet) == FRAME_OK && host_rx.msg_id == PROTO_ID_ACK) {
            proto_ack_t a;
            if (proto_ack_unpack(&a, host_rx.payload, host_rx.payload_len) && a.cmd_id == id) {
                status = a.status;
            }
        }
    }
    return status;
}

static proto_config_motor_t good_motor(void)
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

static proto_config_ctrl_t good_ctrl(void)
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

static proto_profile_segment_t good_segment(void)
{
    proto_profile_segment_t s;
    memset(&s, 0, sizeof s);
    s.duration_s = 1.0f;
    s.speed_rpm = 100.0f;
    s.ramp_rpm_s = 1000.0f;
    s.inject_hz = 10.0f;
    return s;
}

static uint16_t motor(proto_config_motor_t m)
{
    return send(PROTO_ID_CONFIG_MOTOR, proto_config_motor_pack(&m, payload));
}
static uint16_t ctrl(proto_config_ctrl_t c)
{
    return send(PROTO_ID_CONFIG_CTRL, proto_config_ctrl_pack(&c, payload));
}
static uint16_t segment(proto_profile_segment_t s)
{
    return send(PROTO_ID_PROFILE_SEGMENT, proto_profile_segment_pack(&s, payload));
}

static void test_hostile_settings(void)
{
    const float inf = INFINITY, nan = NAN;
    proto_config_motor_t m;
    proto_config_ctrl_t c;
    proto_profile_segment_t s;
    proto_profile_clear_t clr;

    CHECK(motor(good_motor()) == PROTO_ACK_STATUS_OK, "a sane motor is accepted");
    m = good_motor();
    m.i_trip_a = inf;
    CHECK(motor(m) == PROTO_ACK_STATUS_BAD_VALUE, "infinite trip current");
    m = good_motor();
    m.i_trip_a = 1e6f;
    CHECK(motor(m) == PROTO_ACK_STATUS_BAD_VALUE, "trip current over the ceiling");
    m = good_motor();
    m.speed_trip_rpm = inf;
    CHECK(motor(m) == PROTO_ACK_STATUS_BAD_VALUE, "infinite trip speed");
    m = good_motor();
    m.v_dc_max_v = inf;
    CHECK(motor(m) == PROTO_ACK_STATUS_BAD_VALUE, "infinite DC limit");
    m = good_motor();
    m.r_s_ohm = nan;
    CHECK(motor(m) == PROTO_ACK_STATUS_BAD_VALUE, "NaN resistance");

    CHECK(ctrl(good_ctrl()) == PROTO_ACK_STATUS_OK, "a sane control config is accepted");
    c = good_ctrl();
    c.heartbeat_timeout_s = inf;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "infinite heartbeat timeout");
    c = good_ctrl();
    c.heartbeat_timeout_s = 1e9f;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "heartbeat timeout over the ceiling");
    c = good_ctrl();
    c.heartbeat_timeout_s = nan;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "NaN heartbeat timeout");
    c = good_ctrl();
    c.speed_kp_a_per_rad_s = nan;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "NaN speed gain");
    c = good_ctrl();
    c.speed_ki_a_per_rad = inf;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "infinite speed gain");
    c = good_ctrl();
    c.rho = nan;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "NaN rho");
    c = good_ctrl();
    c.enc_offset_e_rad = nan;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "NaN encoder offset");
    c = good_ctrl();
    c.dead_time_s = inf;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "infinite dead time");
    c = good_ctrl();
    c.mpcc_candidates = 2u;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "unknown MPCC candidate set");
    c = good_ctrl();
    c.current_ctrl = 9u;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "unknown current controller");
    c = good_ctrl();
    c.angle_src = 9u;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "unknown angle source");
    c = good_ctrl();
    c.est_bw_rad_s = nan;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "NaN estimator bandwidth");
    c = good_ctrl();
    c.foc_bw_rad_s = 1e9f;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "FOC bandwidth beyond half the control rate");
    c = good_ctrl();
    c.est_lock_timeout_s = -1.0f;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "negative lock timeout");
    c = good_ctrl();
    c.current_ctrl = PROTO_CURRENT_CTRL_FOC;
    c.angle_src = PROTO_ANGLE_SRC_MRAS;
    c.mpcc_candidates = PROTO_MPCC_CANDIDATES_ADJACENT;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_OK, "FOC with the MRAS is accepted");
    CHECK(ctrl(good_ctrl()) == PROTO_ACK_STATUS_OK, "the sane config again");

    clr.n_segments = 1u;
    CHECK(send(PROTO_ID_PROFILE_CLEAR, proto_profile_clear_pack(&clr, payload)) ==
              PROTO_ACK_STATUS_OK,
          "clear");
    s = good_segment();
    s.speed_rpm = nan;
    CHECK(segment(s) == PROTO_ACK_STATUS_BAD_VALUE, "NaN speed");
    s = good_segment();
    s.load_nm = nan;
    CHECK(segment(s) == PROTO_ACK_STATUS_BAD_VALUE, "NaN load");
    s = good_segment();
    s.load_nm = inf;
    CHECK(segment(s) == PROTO_ACK_STATUS_BAD_VALUE, "infinite load");
    s = good_segment();
    s.duration_s = 1e30f;
    CHECK(segment(s) == PROTO_ACK_STATUS_BAD_VALUE, "a duration whose ticks overflow");
    s = good_segment();
    s.duration_s = nan;
    CHECK(segment(s) == PROTO_ACK_STATUS_BAD_VALUE, "NaN duration");
    s = good_segment();
    s.ramp_rpm_s = nan;
    CHECK(segment(s) == PROTO_ACK_STATUS_BAD_VALUE, "NaN ramp");
    s = good_segment();
    s.inject_a = nan;
    CHECK(segment(s) == PROTO_ACK_STATUS_BAD_VALUE, "NaN injection");
    CHECK(segment(good_segment()) == PROTO_ACK_STATUS_OK, "a sane segment is accepted");
}

static void test_nan_measurement_trips(void)
{
    fw_meas_t meas = { 0.0f, 0.0f, 0.0f, 540.0f, 0u };
    fw_cmd_t cmd;
    proto_start_t st = { 0u };
    uint16_t i;

    CHECK(send(PROTO_ID_START, proto_start_pack(&st, payload)) == PROTO_ACK_STATUS_OK, "start");
    for (i = 0u; i < 10u; i++) {
        fw_isr(&fw, &meas, &cmd);
    }
    CHECK(fw_state(&fw) == PROTO_STATE_RUNNING, "running on sane measurements");
    meas.i_b_a = NAN;
    fw_isr(&fw, &meas, &cmd);
    CHECK(fw_state(&fw) == PROTO_STATE_FAULT, "a NaN phase current trips at once");
}

int main(void)
{
    fw_cfg_t cfg = { PROTO_BOARD_EMULATOR, 1u };
    fw_init(&fw, &cfg);
    frame_parser_init(&host_rx);
    test_hostile_settings();
    test_nan_measurement_trips();
    return CHECK_DONE();
}
