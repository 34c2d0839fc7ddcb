/* libFuzzer target: the serial frame parser (core/frame.c) on arbitrary octet streams.
 * Invariants (abort on failure): every accepted frame has a payload within PROTO_MAX_PAYLOAD, the
 * protocol's length for a known id, and re-encodes (frame_encode) to octets that parse back to the
 * same frame; the error counters add up. Built with ASan and UBSan (make -C firmware fuzz). */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "frame.h"

static void check(int ok)
{
    if (!ok) {
        abort();
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static frame_parser_t p, q;
    static uint16_t enc[FRAME_MAX_ENCODED];
    uint16_t payload[PROTO_MAX_PAYLOAD];
    size_t i;
    frame_parser_init(&p);
    for (i = 0; i < size; i++) {
        int16_t r = frame_parser_push(&p, data[i]);
        check(r >= FRAME_ERR_SHORT && r <= FRAME_OK);
        if (r == FRAME_OK) {
            int16_t want = proto_payload_len(p.msg_id);
            uint16_t n = p.payload_len, k, m;
            int16_t r2 = FRAME_NONE;
            check(n <= PROTO_MAX_PAYLOAD && p.msg_id <= 0xFFu && p.seq <= 0xFFu);
            check(want < 0 || (uint16_t)want == n);
            memcpy(payload, p.payload, n * sizeof(uint16_t));
            m = frame_encode(p.msg_id, p.seq, payload, n, enc, FRAME_MAX_ENCODED);
            check(m > 0u && enc[m - 1u] == 0u);
            frame_parser_init(&q);
            for (k = 0u; k < m; k++) {
                r2 = frame_parser_push(&q, enc[k]);
                check(k + 1u == m || r2 == FRAME_NONE);
            }
            check(r2 == FRAME_OK && q.msg_id == p.msg_id && q.seq == p.seq && q.payload_len == n &&
                  memcmp(q.payload, payload, n * sizeof(uint16_t)) == 0);
        }
    }
    check(p.frames_bad == p.err_crc + p.err_cobs + p.err_len + p.err_short);
    return 0;
}
