/* libFuzzer target: the whole firmware on the sim board (sim/board.c, the emulator's C API) fed
 * arbitrary command streams on its serial link.
 *
 * The input is a sequence of operations, each led by one octet op:
 *   op < 0x40         the next op + 1 octets go to the UART as they are (noise, torn frames);
 *   0x40 <= op < 0xC0 a well-formed frame: id = next octet, seq = op, payload = the protocol's
 *                     length for the id (else next octet % (PROTO_MAX_PAYLOAD + 1)) of the
 *                     following octets (zeros past the end), COBS + CRC encoded;
 *   op >= 0xC0        (op - 0xBF) * 16 control periods run without input.
 * After the input, the host falls silent.
 *
 * Invariants (abort on failure), besides ASan and UBSan: every octet the device sends parses into
 * valid frames (no CRC, COBS, length or short-frame error in the host's parser); the state is one
 * of the protocol's; after every stretch of control periods (the input's silences included), a
 * motor still `running` had its last heartbeat no longer ago than the heartbeat timeout the
 * firmware accepted plus one control period; once the host is silent for good, a running motor
 * leaves `running` within that time, and the PWM is off (the firmware inactive) within the stop's
 * own time limit after that. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "emu.h"
#include "frame.h"
#include "proto_gen.h"

#define OUT_CAP    (1u << 16)
#define STOP_MAX_S 3.0 /* FW_STOP_TIMEOUT_S */

static void check(int ok)
{
    if (!ok) {
        abort();
    }
}

static emu_t *e;
static uint8_t out[OUT_CAP];
static frame_parser_t host;
static unsigned long n_inputs, n_running_at_silence, n_frames_out, n_running_checked;

static void report(void)
{
    fprintf(stderr,
            "fuzz_fw: inputs %lu, running when the host fell silent %lu (stopped in time: all), "
            "heartbeat age checked while running %lu times, device frames parsed %lu\n",
            n_inputs, n_running_at_silence, n_running_checked, n_frames_out);
}

/* Heartbeat timeout + one control period, in control periods (the firmware's accepted values). */
static uint32_t hb_limit(void)
{
    double timeout_s, ts_s;
    emu_heartbeat_cfg(e, &timeout_s, &ts_s);
    check(ts_s > 0.0 && timeout_s > 0.0 && timeout_s <= 10.0);
    return (uint32_t)ceil(timeout_s / ts_s) + 1u;
}

/* Run up to n periods; every octet sent goes through the host's parser. */
static uint32_t run(uint32_t n)
{
    uint32_t done = 0u, ran, n_out, i;
    do {
        ran = emu_run(e, n - done, out, OUT_CAP, &n_out);
        for (i = 0u; i < n_out; i++) {
            if (frame_parser_push(&host, out[i]) == FRAME_OK) {
                n_frames_out++;
            }
        }
        check(host.frames_bad == 0u);
        check(emu_state(e) >= PROTO_STATE_IDLE && emu_state(e) <= PROTO_STATE_DONE);
        if (emu_active(e) && emu_state(e) == PROTO_STATE_RUNNING) {
            n_running_checked++;
            check(emu_isr_count(e) - emu_heartbeat_isr(e) <= hb_limit());
        }
        done += ran;
    } while (done < n && ran > 0u);
    return done;
}

static void send_frame(uint16_t id, uint16_t seq, const uint8_t *p, size_t avail, size_t *used)
{
    uint16_t payload[PROTO_MAX_PAYLOAD], enc[FRAME_MAX_ENCODED];
    uint8_t octets[FRAME_MAX_ENCODED];
    int16_t want = proto_payload_len(id);
    uint16_t n, k, m;
    size_t u = 0u;
    if (want >= 0) {
        n = (uint16_t)want;
    } else {
        n = (uint16_t)((avail > 0u ? p[u++] : 0u) % (PROTO_MAX_PAYLOAD + 1u));
    }
    for (k = 0u; k < n; k++) {
        payload[k] = u < avail ? p[u++] : 0u;
    }
    m = frame_encode(id, seq, payload, n, enc, FRAME_MAX_ENCODED);
    for (k = 0u; k < m; k++) {
        octets[k] = (uint8_t)enc[k];
    }
    emu_rx(e, octets, m);
    *used = u;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    size_t i = 0u;
    if (e == NULL) {
        e = (emu_t *)malloc(emu_size());
        check(e != NULL);
        atexit(report);
    }
    n_inputs++;
    emu_init(e);
    emu_reset(e);
    frame_parser_init(&host);
    while (i < size) {
        uint8_t op = data[i++];
        if (op < 0x40u) {
            size_t n = (size_t)op + 1u;
            if (n > size - i) {
                n = size - i;
            }
            emu_rx(e, &data[i], (uint32_t)n);
            i += n;
        } else if (op < 0xC0u) {
            size_t used = 0u;
            uint16_t id = i < size ? data[i++] : 0u;
            send_frame(id, op, &data[i], size - i, &used);
            i += used;
        } else {
            (void)run((uint32_t)(op - 0xBFu) * 16u);
        }
    }
    /* the host falls silent */
    if (emu_active(e) && emu_state(e) == PROTO_STATE_RUNNING) {
        double timeout_s, ts_s;
        uint32_t hb, limit, hb_isr;
        n_running_at_silence++;
        emu_heartbeat_cfg(e, &timeout_s, &ts_s);
        limit = hb_limit(); /* timeout + one control period */
        hb = emu_heartbeat_isr(e);
        while (emu_state(e) == PROTO_STATE_RUNNING && emu_isr_count(e) - hb <= limit + 1u) {
            if (run(1u) == 0u) {
                break;
            }
        }
        check(emu_state(e) != PROTO_STATE_RUNNING);
        check(emu_state_change(e, &hb_isr) - hb_isr <= limit);
        (void)run((uint32_t)ceil(STOP_MAX_S / ts_s) + 2u);
        check(!emu_active(e));
    }
    return 0;
}
