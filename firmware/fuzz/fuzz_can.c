/* libFuzzer target: CAN reassembly of the firmware (core/can_link.c), two ways.
 *
 * Raw (first octet even): the rest is a sequence of frames [id_hi, id_lo, dlc, data...] fed to
 * can_link_rx. Every message it accepts must have the protocol's length for its id (an unknown or
 * device-to-host id can come only by transfer, for the dispatcher to refuse, as on serial), its
 * end-to-end CRC (a transfer's header CRC, a multi-frame direct message's CRC frame) must match
 * msg_id, seq and payload, and the counters must add up.
 *
 * Lossy (first octet odd): messages of the h2d kinds are built from the input, queued as frames by
 * can_link_send, and frames are lost (in bursts), repeated or taken from the input's choice before
 * can_link_rx. An accepted message that was not sent is a splice that passed every check; it is
 * counted (a CRC-16 lets one in 65536 such splices through, so it is a figure, not a crash) and
 * reported at exit with the number of splices the CRC stopped. */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "can_link.h"
#include "frame.h"

#define MAX_SENT 16u

static void check(int ok)
{
    if (!ok) {
        abort();
    }
}

static unsigned long n_accepted, n_crc_stopped, n_spliced_accepted;

static void report(void)
{
    fprintf(stderr,
            "fuzz_can: accepted %lu, stopped by the end-to-end CRC %lu, not-sent accepted %lu\n",
            n_accepted, n_crc_stopped, n_spliced_accepted);
}

static void check_accepted(const can_link_t *c)
{
    proto_can_layout_t l;
    uint16_t in[PROTO_MAX_PAYLOAD + 2u], i;
    int16_t want = proto_payload_len(c->msg_id);
    bool known = proto_can_layout(c->msg_id, &l);
    check(c->payload_len <= PROTO_MAX_PAYLOAD && c->msg_id <= 0xFFu && c->seq <= 0xFFu);
    /* a known id has its length; an id the protocol does not know, or a device-to-host id, can
     * only come by transfer (as on serial, the dispatcher refuses it: ack "unknown") */
    check(want < 0 || (uint16_t)want == c->payload_len);
    check((known && l.h2d != 0u && l.transfer == 0u) || c->x_len == c->payload_len);
    in[0] = c->msg_id;
    in[1] = c->seq;
    for (i = 0u; i < c->payload_len; i++) {
        check(c->payload[i] <= 0xFFu);
        in[2u + i] = c->payload[i];
    }
    if (!known || l.transfer != 0u || l.h2d == 0u) {
        check(frame_crc16(in, (uint16_t)(c->payload_len + 2u)) == c->x_crc);
    } else if (l.crc_frame != PROTO_CAN_NO_CRC) {
        check(frame_crc16(in, (uint16_t)(c->payload_len + 2u)) == c->rx_crc);
    }
    n_accepted++;
}

static void raw(const uint8_t *d, size_t n)
{
    static can_link_t c;
    uint16_t data[8], k;
    size_t at = 0;
    uint32_t errs = 0u;
    can_link_init(&c, d[0] & 0x0Fu);
    while (at + 3u <= n) {
        uint16_t id = (uint16_t)(((d[at] << 8) | d[at + 1u]) & 0x7FFu);
        uint16_t dlc = (uint16_t)(d[at + 2u] & 0x0Fu); /* 9..15 must be refused */
        int16_t r;
        at += 3u;
        for (k = 0u; k < 8u; k++) {
            data[k] = (at + k < n) ? d[at + k] : 0u;
        }
        at += dlc > 8u ? 8u : dlc;
        r = can_link_rx(&c, id, data, dlc);
        check(r >= CAN_RX_ERR_CRC && r <= CAN_RX_MSG);
        if (r == CAN_RX_MSG) {
            check_accepted(&c);
        } else if (r < 0) {
            errs++;
        }
    }
    check(c.err_unknown + c.err_len + c.err_order + c.err_crc >= errs);
}

/* h2d message kinds: the ones the host sends (direct and by transfer) */
static const uint16_t H2D[] = {
    PROTO_ID_HELLO,           PROTO_ID_CONFIG_MOTOR, PROTO_ID_CONFIG_CTRL, PROTO_ID_PROFILE_CLEAR,
    PROTO_ID_PROFILE_SEGMENT, PROTO_ID_START,        PROTO_ID_STOP,        PROTO_ID_ABORT,
    PROTO_ID_HEARTBEAT,       PROTO_ID_CAPTURE_READ, PROTO_ID_SIM_PLANT
};

static void lossy(const uint8_t *d, size_t n)
{
    static can_link_t tx, rx;
    static uint16_t sent[MAX_SENT][PROTO_MAX_PAYLOAD + 2u];
    static uint16_t sent_len[MAX_SENT];
    uint16_t n_sent = 0u, burst = 0u, i;
    size_t at = 1;
    can_frame_t fr;
    can_link_init(&tx, 1u);
    can_link_init(&rx, 1u);
    /* messages: [kind, seq, payload octets...] while the input lasts */
    while (n_sent < MAX_SENT && at + 2u <= n) {
        uint16_t id = H2D[d[at] % (sizeof H2D / sizeof H2D[0])];
        uint16_t len = (uint16_t)proto_payload_len(id), seq = d[at + 1u];
        at += 2u;
        sent[n_sent][0] = id;
        sent[n_sent][1] = seq;
        for (i = 0u; i < len; i++) {
            sent[n_sent][2u + i] = (at < n) ? d[at++] : (uint16_t)(i * 37u & 0xFFu);
        }
        sent_len[n_sent] = len;
        if (!can_link_send(&tx, id, seq, &sent[n_sent][2], len)) {
            break;
        }
        n_sent++;
    }
    /* the bus: the remaining input octets choose each frame's fate */
    while (can_link_tx_pop(&tx, &fr)) {
        uint16_t fate = at < n ? d[at++] : 0u;
        int16_t r;
        uint16_t rep, times = 1u;
        if (burst > 0u) {
            burst--;
            continue;
        }
        if ((fate & 0xC0u) == 0xC0u) { /* a burst of 1..8 frames lost, this one first */
            burst = (uint16_t)(fate & 7u);
            continue;
        }
        if ((fate & 0xF0u) == 0x80u) {
            times = 2u; /* repeated */
        }
        for (rep = 0u; rep < times; rep++) {
            r = can_link_rx(&rx, fr.id, fr.data, fr.dlc);
            if (r == CAN_RX_ERR_CRC) {
                n_crc_stopped++;
            }
            if (r == CAN_RX_MSG) {
                uint16_t k, found = 0u;
                check_accepted(&rx);
                for (k = 0u; k < n_sent && !found; k++) {
                    found = (uint16_t)(sent[k][0] == rx.msg_id && sent[k][1] == rx.seq &&
                                       sent_len[k] == rx.payload_len &&
                                       memcmp(&sent[k][2], rx.payload,
                                              rx.payload_len * sizeof(uint16_t)) == 0);
                }
                n_spliced_accepted += found ? 0u : 1u;
            }
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *d, size_t n)
{
    static int registered;
    if (!registered) {
        registered = 1;
        atexit(report);
    }
    if (n == 0u) {
        return 0;
    }
    if ((d[0] & 1u) == 0u) {
        raw(d, n);
    } else {
        lossy(d, n);
    }
    return 0;
}
