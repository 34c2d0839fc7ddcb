/* The quick stop ends once the rotor is still: the speed's mean over a 50 ms window below 3 r/min.
 * An encoder at the edge of a count (its speed toggling by a few r/min around zero) is still; a
 * rotor turning at 10 r/min is not, and its stop ends at the 3 s timeout. `stop_at` stops a run at
 * the tick it names, as `stop` would, and only that run. */
#include <math.h>

#include "fw_host.h"

/* One stop after a 10 ms profile at zero speed: the encoder count follows count_at(period). Returns
 * the periods from the profile's end to PWM off; *peak_rpm: the largest |speed| the firmware saw. */
static uint32_t stop_periods(uint32_t (*count_at)(uint32_t), float *peak_rpm)
{
    fw_meas_t meas = { 0.0f, 0.0f, 0.0f, 540.0f, 0u };
    fw_cmd_t cmd;
    proto_profile_segment_t s;
    uint32_t k = 0u, end = 0u;
    proto_config_ctrl_t c = host_good_ctrl();
    c.heartbeat_timeout_s = 5.0f;   /* the 3 s stop timeout comes first */
    c.speed_obs_bw_rad_s = 3000.0f; /* a fast observer: a count's step shows as some r/min */
    c.fast_div = 100u;
    memset(&s, 0, sizeof s);
    s.duration_s = 0.01f;
    host_configure(&c, &s);
    host_start();
    *peak_rpm = 0.0f;
    while (fw_active(&fw) && k < 100000u) {
        meas.enc_count = count_at(k);
        fw_isr(&fw, &meas, &cmd);
        host_collect();
        if (fw_state(&fw) == PROTO_STATE_STOPPING) {
            end = end == 0u ? k : end;
            *peak_rpm = fmaxf(*peak_rpm, fabsf(fw.ang.speed_rpm));
        }
        k++;
    }
    CHECK(!fw_active(&fw) && end > 0u, "the run ends through a stop");
    return k - end;
}

static uint32_t at_an_edge(uint32_t k)
{
    return 5000u + ((k / 40u) & 1u); /* one count back and forth every 2 ms */
}

static uint32_t turning(uint32_t k)
{
    return 5000u + k / 12u; /* 10000 counts per turn: 10 r/min */
}

/* Periods from start until the run leaves RUNNING, with stop_at(at) sent before start when at > 0;
 * the profile: 0.1 s at zero speed. *reason: the stopped event's reason. */
static uint32_t run_until_stopping(uint32_t at, int32_t *reason)
{
    fw_meas_t meas = { 0.0f, 0.0f, 0.0f, 540.0f, 5000u };
    fw_cmd_t cmd;
    proto_config_ctrl_t c = host_good_ctrl();
    proto_profile_segment_t s;
    uint32_t k = 0u, left = 0u;
    memset(&s, 0, sizeof s);
    s.duration_s = 0.1f;
    host_configure(&c, &s);
    if (at > 0u) {
        proto_stop_at_t a = { at };
        CHECK(host_send(PROTO_ID_STOP_AT, proto_stop_at_pack(&a, payload)) == PROTO_ACK_STATUS_OK,
              "stop_at");
    }
    host_start();
    while (fw_active(&fw) && k < 20000u) {
        fw_isr(&fw, &meas, &cmd);
        if (left == 0u && fw_state(&fw) != PROTO_STATE_RUNNING) {
            left = fw_tick(&fw);
        }
        k++;
    }
    *reason = fw.stop_reason;
    host_collect();
    return left;
}

int main(void)
{
    fw_cfg_t cfg = { PROTO_BOARD_EMULATOR, 1u };
    uint32_t n;
    float peak;
    fw_init(&fw, &cfg);
    frame_parser_init(&host_rx);

    n = stop_periods(at_an_edge, &peak);
    CHECK(peak > 3.0f, "the encoder's speed at the edge of a count swings beyond 3 r/min");
    CHECK(n * 50e-6f < 0.2f, "a rotor still on average: PWM off within a few 50 ms windows");

    n = stop_periods(turning, &peak);
    CHECK(n * 50e-6f > 2.9f && n * 50e-6f < 3.1f, "a turning rotor: PWM off at the 3 s timeout");

    {
        int32_t reason = -1;
        n = run_until_stopping(300u, &reason);
        CHECK(n == 301u, "stop_at 300: the run stops in the period of tick 300");
        CHECK(reason == PROTO_STOP_REASON_HOST_STOP, "as a host stop");
        n = run_until_stopping(0u, &reason);
        CHECK(n > 1990u && reason == PROTO_STOP_REASON_PROFILE_END,
              "the next run, without stop_at, runs its whole profile");
    }
    return CHECK_DONE();
}
