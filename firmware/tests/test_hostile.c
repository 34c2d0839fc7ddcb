/* The firmware refuses settings that would switch its own protection off (non-finite values,
 * an unbounded heartbeat timeout, trip limits beyond the hard ceilings, durations whose tick
 * count would overflow), and a non-finite measurement trips it. */
#include <math.h>

#include "fw_host.h"

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
    return host_send(PROTO_ID_CONFIG_MOTOR, proto_config_motor_pack(&m, payload));
}
static uint16_t ctrl(proto_config_ctrl_t c)
{
    return host_send(PROTO_ID_CONFIG_CTRL, proto_config_ctrl_pack(&c, payload));
}
static uint16_t segment(proto_profile_segment_t s)
{
    return host_send(PROTO_ID_PROFILE_SEGMENT, proto_profile_segment_pack(&s, payload));
}

static void test_hostile_settings(void)
{
    const float inf = INFINITY, nan = NAN;
    proto_config_motor_t m;
    proto_config_ctrl_t c;
    proto_profile_segment_t s;
    proto_profile_clear_t clr;

    CHECK(motor(host_good_motor()) == PROTO_ACK_STATUS_OK, "a sane motor is accepted");
    m = host_good_motor();
    m.i_trip_a = inf;
    CHECK(motor(m) == PROTO_ACK_STATUS_BAD_VALUE, "infinite trip current");
    m = host_good_motor();
    m.i_trip_a = 1e6f;
    CHECK(motor(m) == PROTO_ACK_STATUS_BAD_VALUE, "trip current over the ceiling");
    m = host_good_motor();
    m.speed_trip_rpm = inf;
    CHECK(motor(m) == PROTO_ACK_STATUS_BAD_VALUE, "infinite trip speed");
    m = host_good_motor();
    m.v_dc_max_v = inf;
    CHECK(motor(m) == PROTO_ACK_STATUS_BAD_VALUE, "infinite DC limit");
    m = host_good_motor();
    m.r_s_ohm = nan;
    CHECK(motor(m) == PROTO_ACK_STATUS_BAD_VALUE, "NaN resistance");

    CHECK(ctrl(host_good_ctrl()) == PROTO_ACK_STATUS_OK, "a sane control config is accepted");
    c = host_good_ctrl();
    c.heartbeat_timeout_s = inf;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "infinite heartbeat timeout");
    c = host_good_ctrl();
    c.heartbeat_timeout_s = 1e9f;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "heartbeat timeout over the ceiling");
    c = host_good_ctrl();
    c.heartbeat_timeout_s = nan;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "NaN heartbeat timeout");
    c = host_good_ctrl();
    c.speed_kp_a_per_rad_s = nan;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "NaN speed gain");
    c = host_good_ctrl();
    c.speed_ki_a_per_rad = inf;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "infinite speed gain");
    c = host_good_ctrl();
    c.rho = nan;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "NaN rho");
    c = host_good_ctrl();
    c.enc_offset_e_rad = nan;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "NaN encoder offset");
    c = host_good_ctrl();
    c.dead_time_s = inf;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "infinite dead time");
    c = host_good_ctrl();
    c.mpcc_candidates = 2u;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "unknown MPCC candidate set");
    c = host_good_ctrl();
    c.current_ctrl = 9u;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "unknown current controller");
    c = host_good_ctrl();
    c.angle_src = 9u;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "unknown angle source");
    c = host_good_ctrl();
    c.est_bw_rad_s = nan;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "NaN estimator bandwidth");
    c = host_good_ctrl();
    c.foc_bw_rad_s = 1e9f;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "FOC bandwidth beyond half the control rate");
    c = host_good_ctrl();
    c.est_lock_timeout_s = -1.0f;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_BAD_VALUE, "negative lock timeout");
    c = host_good_ctrl();
    c.current_ctrl = PROTO_CURRENT_CTRL_FOC;
    c.angle_src = PROTO_ANGLE_SRC_MRAS;
    c.mpcc_candidates = PROTO_MPCC_CANDIDATES_ADJACENT;
    CHECK(ctrl(c) == PROTO_ACK_STATUS_OK, "FOC with the MRAS is accepted");
    CHECK(ctrl(host_good_ctrl()) == PROTO_ACK_STATUS_OK, "the sane config again");

    clr.n_segments = 1u;
    CHECK(host_send(PROTO_ID_PROFILE_CLEAR, proto_profile_clear_pack(&clr, payload)) ==
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

    CHECK(host_send(PROTO_ID_START, proto_start_pack(&st, payload)) == PROTO_ACK_STATUS_OK,
          "start");
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
