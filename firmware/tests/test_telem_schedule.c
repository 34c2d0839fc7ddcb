/* The telemetry schedule: fast frames go out at every tick that is a multiple of fast_div, status
 * frames at their phase of status_div, from the first tick of a run to the last, and a second run
 * with other dividers follows its own (the phases are carried from period to period, fw_msg.c). */
#include "fw_host.h"

#define MAX_SEEN 4096u
static uint32_t fast_ticks[MAX_SEEN], status_ticks[MAX_SEEN];
static uint32_t n_fast, n_status;

static void on_frame(const frame_parser_t *rx)
{
    if (rx->msg_id == PROTO_ID_TELEM_FAST && n_fast < MAX_SEEN) {
        proto_telem_fast_t t;
        if (proto_telem_fast_unpack(&t, rx->payload, rx->payload_len)) {
            fast_ticks[n_fast++] = t.tick;
        }
    } else if (rx->msg_id == PROTO_ID_STATUS && n_status < MAX_SEEN) {
        proto_status_t s;
        if (proto_status_unpack(&s, rx->payload, rx->payload_len)) {
            status_ticks[n_status++] = s.tick;
        }
    }
}

static void configure(uint16_t fast_div, uint16_t status_div)
{
    proto_config_ctrl_t c = host_good_ctrl();
    proto_profile_segment_t s;
    c.fast_div = fast_div;
    c.status_div = status_div;
    memset(&s, 0, sizeof s);
    s.duration_s = 0.02f; /* 400 periods, then the stop */
    host_configure(&c, &s);
}

/* One run from start to rest; returns the number of periods it lasted. */
static uint32_t run(void)
{
    fw_meas_t meas = { 0.0f, 0.0f, 0.0f, 540.0f, 0u };
    fw_cmd_t cmd;
    uint32_t k = 0u;
    n_fast = 0u;
    n_status = 0u;
    host_start();
    while (fw_active(&fw) && k < 20000u) {
        fw_isr(&fw, &meas, &cmd);
        host_collect();
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
    host_on_frame = on_frame;

    configure(10u, 200u);
    periods = run();
    check_schedule(periods, 10u, 200u, 5u); /* status phase: after the params slots (fw_msg.c) */

    /* the next run with other dividers: the phases start again from its tick 0 */
    configure(7u, 50u);
    periods = run();
    check_schedule(periods, 7u, 50u, 5u);
    return CHECK_DONE();
}
