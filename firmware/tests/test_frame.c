/* Framing and generated pack/unpack against the golden frames shared with the Python tests. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "frame.h"
#include "golden_frames.h"
#include "proto_gen.h"

static frame_parser_t parser; /* large: keep it off the stack */

/* Pushes n octets; returns how many FRAME_OK results they produced. */
static int push_all(frame_parser_t *p, const uint16_t *d, uint16_t n)
{
    int ok = 0;
    uint16_t i;
    for (i = 0u; i < n; i++) {
        if (frame_parser_push(p, d[i]) == FRAME_OK) {
            ok++;
        }
    }
    return ok;
}

static bool same_octets(const uint16_t *a, const uint16_t *b, uint16_t n)
{
    return n == 0u || memcmp(a, b, n * sizeof(uint16_t)) == 0;
}

/* True when the parser's last frame is exactly golden frame g. */
static bool parser_holds(const frame_parser_t *p, const golden_frame_t *g)
{
    return p->msg_id == g->msg_id && p->seq == g->seq && p->payload_len == g->payload_len &&
           same_octets(p->payload, g->payload, g->payload_len);
}

static void test_crc(void)
{
    static const uint16_t digits[9] = { '1', '2', '3', '4', '5', '6', '7', '8', '9' };
    CHECK(frame_crc16(digits, 9u) == 0x29B1u, "CRC-16/CCITT-FALSE check value");
    CHECK(frame_crc16(digits, 0u) == 0xFFFFu, "CRC of nothing is the init value");
}

static void test_golden_pack_encode(void)
{
    uint16_t k;
    for (k = 0u; k < GOLDEN_FRAME_COUNT; k++) {
        const golden_frame_t *g = &golden_frames[k];
        uint16_t payload[PROTO_MAX_PAYLOAD + 1u];
        uint16_t out[FRAME_MAX_ENCODED];
        uint16_t n = g->pack(payload);
        uint16_t len;
        char msg[160];
        snprintf(msg, sizeof msg, "golden %u (%s): pack reproduces the payload", (unsigned)k,
                 g->label);
        CHECK(n == g->payload_len && same_octets(payload, g->payload, n), msg);
        CHECK(proto_payload_len(g->msg_id) == (int16_t)g->payload_len, "proto_payload_len");
        len = frame_encode(g->msg_id, g->seq, payload, n, out, FRAME_MAX_ENCODED);
        snprintf(msg, sizeof msg, "golden %u (%s): frame_encode reproduces the frame", (unsigned)k,
                 g->label);
        CHECK(len == g->frame_len && same_octets(out, g->frame, len), msg);
        /* exactly the frame's length fits, one less does not */
        CHECK(frame_encode(g->msg_id, g->seq, payload, n, out, g->frame_len) == g->frame_len,
              "exact fit");
        CHECK(frame_encode(g->msg_id, g->seq, payload, n, out, (uint16_t)(g->frame_len - 1u)) == 0u,
              "one octet short: 0");
        g->check(g->payload, g->payload_len);
    }
}

static void test_golden_parse(void)
{
    uint16_t k;
    int ok = 0;
    frame_parser_init(&parser);
    for (k = 0u; k < GOLDEN_FRAME_COUNT; k++) {
        const golden_frame_t *g = &golden_frames[k];
        uint16_t i;
        for (i = 0u; i < g->frame_len; i++) {
            int16_t r = frame_parser_push(&parser, g->frame[i]);
            if (i + 1u < g->frame_len) {
                CHECK(r == FRAME_NONE, "no result before the delimiter");
            } else if (r == FRAME_OK && parser_holds(&parser, g)) {
                ok++;
                g->check(parser.payload, parser.payload_len);
            }
        }
    }
    CHECK(ok == (int)GOLDEN_FRAME_COUNT, "every golden frame parses back");
    CHECK(parser.frames_ok == GOLDEN_FRAME_COUNT && parser.frames_bad == 0u,
          "counters after golden frames");
}

/* Every single-bit flip of every golden frame (delimiter included) is rejected, and the parser takes
 * the next intact frame after the following 0x00. */
static void test_bit_flips(void)
{
    uint16_t k;
    long flips = 0, accepted = 0, resync_fail = 0;
    for (k = 0u; k < GOLDEN_FRAME_COUNT; k++) {
        const golden_frame_t *g = &golden_frames[k];
        uint16_t pos, bit;
        for (pos = 0u; pos < g->frame_len; pos++) {
            for (bit = 0u; bit < 8u; bit++) {
                uint16_t bad[FRAME_MAX_ENCODED + 1u];
                uint16_t zero = 0u;
                memcpy(bad, g->frame, g->frame_len * sizeof(uint16_t));
                bad[pos] = (uint16_t)(bad[pos] ^ (1u << bit));
                frame_parser_init(&parser);
                accepted += push_all(&parser, bad, g->frame_len);
                accepted += push_all(&parser, &zero, 1u);
                if (push_all(&parser, g->frame, g->frame_len) != 1 || !parser_holds(&parser, g)) {
                    resync_fail++;
                }
                flips++;
            }
        }
    }
    printf("bit flips: %ld tried, %ld accepted, %ld resync failures\n", flips, accepted,
           resync_fail);
    CHECK(accepted == 0, "no single-bit flip is accepted");
    CHECK(resync_fail == 0, "the parser resynchronises after each flipped frame");
}

/* Every truncation of every golden frame is rejected. */
static void test_truncation(void)
{
    uint16_t k;
    long accepted = 0, resync_fail = 0;
    for (k = 0u; k < GOLDEN_FRAME_COUNT; k++) {
        const golden_frame_t *g = &golden_frames[k];
        uint16_t keep;
        for (keep = 1u; keep + 1u < g->frame_len; keep++) {
            uint16_t zero = 0u;
            frame_parser_init(&parser);
            accepted += push_all(&parser, g->frame, keep);
            accepted += push_all(&parser, &zero, 1u);
            if (push_all(&parser, g->frame, g->frame_len) != 1 || !parser_holds(&parser, g)) {
                resync_fail++;
            }
        }
    }
    CHECK(accepted == 0, "no truncated frame is accepted");
    CHECK(resync_fail == 0, "the parser resynchronises after each truncated frame");
}

static void test_errors(void)
{
    static const uint16_t empty[3] = { 0u, 0u, 0u };
    static const uint16_t short1[2] = { 0x01u, 0x00u };
    static const uint16_t short3[4] = { 0x03u, 0x11u, 0x22u, 0x00u };
    static const uint16_t cobs_bad[3] = { 0x05u, 0x11u, 0x00u };
    const golden_frame_t *g = &golden_frames[0];
    uint16_t i;
    int16_t r, first_err = FRAME_NONE;

    frame_parser_init(&parser);
    CHECK(push_all(&parser, empty, 3u) == 0 && parser.frames_bad == 0u,
          "idle zeros are not errors");
    (void)push_all(&parser, short1, 2u);
    (void)push_all(&parser, short3, 4u);
    CHECK(parser.err_short == 2u, "frames under 4 octets: FRAME_ERR_SHORT");
    (void)push_all(&parser, cobs_bad, 3u);
    CHECK(parser.err_cobs == 1u, "a frame ending inside a COBS block: FRAME_ERR_COBS");

    /* overflow: a long run without a delimiter is reported once, then skipped */
    frame_parser_init(&parser);
    for (i = 0u; i < 3u * FRAME_MAX_ENCODED; i++) {
        r = frame_parser_push(&parser, 0x55u);
        if (r != FRAME_NONE && first_err == FRAME_NONE) {
            first_err = r;
        }
    }
    CHECK(first_err == FRAME_ERR_LEN && parser.err_len == 1u, "overflow: one FRAME_ERR_LEN");
    CHECK(frame_parser_push(&parser, 0u) == FRAME_NONE, "the delimiter ends the skipped frame");
    CHECK(push_all(&parser, g->frame, g->frame_len) == 1 && parser_holds(&parser, g),
          "resync after overflow");

    /* garbage glued to the front of a frame loses that frame only */
    frame_parser_init(&parser);
    (void)frame_parser_push(&parser, 0x42u);
    CHECK(push_all(&parser, g->frame, g->frame_len) == 0 && parser.err_crc + parser.err_cobs == 1u,
          "a frame with leading garbage is rejected");
    CHECK(push_all(&parser, g->frame, g->frame_len) == 1 && parser_holds(&parser, g),
          "the next one is taken");
    CHECK(parser.frames_ok == 1u && parser.frames_bad == 1u, "good and bad counters");
}

static void test_encode_limits(void)
{
    uint16_t payload[PROTO_MAX_PAYLOAD + 1u];
    uint16_t out[2u * FRAME_MAX_ENCODED];
    uint16_t len;
    memset(payload, 0, sizeof payload);
    CHECK(proto_payload_len(0xFFu) == -1, "0xFF is not a message id");
    len = frame_encode(0xFFu, 0u, payload, PROTO_MAX_PAYLOAD, out, FRAME_MAX_ENCODED);
    CHECK(len > 0u && len <= FRAME_MAX_ENCODED, "the longest payload fits in FRAME_MAX_ENCODED");
    CHECK(frame_encode(0xFFu, 0u, payload, PROTO_MAX_PAYLOAD + 1u, out, 2u * FRAME_MAX_ENCODED) ==
              0u,
          "a payload over PROTO_MAX_PAYLOAD is refused");
    frame_parser_init(&parser);
    CHECK(push_all(&parser, out, len) == 1 && parser.payload_len == PROTO_MAX_PAYLOAD,
          "an unknown id passes the framing, for the dispatcher to refuse");

    /* a known id with the wrong payload length is a framing error */
    len = frame_encode(PROTO_ID_TELEM_FAST, 0u, payload, PROTO_LEN_TELEM_FAST + 1u, out,
                       FRAME_MAX_ENCODED);
    frame_parser_init(&parser);
    CHECK(push_all(&parser, out, len) == 0 && parser.err_len == 1u,
          "known id, wrong length: FRAME_ERR_LEN");
}

static void test_accessors(void)
{
    const golden_frame_t *g = &golden_frames[GOLDEN_FRAME_COUNT - 2u];
    uint16_t out[FRAME_MAX_RAW];
    uint16_t n;
    CHECK(frame_parser_size() == (uint16_t)sizeof(frame_parser_t), "frame_parser_size");
    frame_parser_init(&parser);
    (void)push_all(&parser, g->frame, g->frame_len);
    n = frame_parser_frame(&parser, out, FRAME_MAX_RAW);
    CHECK(n == g->payload_len + 2u && out[0] == g->msg_id && out[1] == g->seq &&
              same_octets(&out[2], g->payload, g->payload_len),
          "frame_parser_frame copies id, seq, payload");
    CHECK(frame_parser_frame(&parser, out, (uint16_t)(g->payload_len + 1u)) == 0u, "too small: 0");
    CHECK(proto_payload_len(0xFFu) == -1, "unknown id: -1");
}

static void test_saturation(void)
{
    proto_telem_fast_t t;
    proto_capture_chunk_t c;
    uint16_t buf[PROTO_MAX_PAYLOAD];
    memset(&t, 0, sizeof t);
    memset(&c, 0, sizeof c);
    t.speed_rpm = NAN;
    t.speed_est_rpm = INFINITY;
    t.speed_ref_rpm = -INFINITY;
    t.theta_e_rad = 1e30f;
    t.i_d_a = -0.0029f; /* -1.45 LSB -> -1 */
    t.i_q_a = -0.0031f; /* -1.55 LSB -> -2 */
    CHECK(proto_telem_fast_pack(&t, buf) == PROTO_LEN_TELEM_FAST, "pack length");
    CHECK(proto_telem_fast_unpack(&t, buf, PROTO_LEN_TELEM_FAST), "unpack");
    CHECK_NEAR(t.speed_rpm, 0.0, 0.0, "NaN -> 0");
    CHECK_NEAR(t.speed_est_rpm, 3276.7, 1e-3, "+inf saturates");
    CHECK_NEAR(t.speed_ref_rpm, -3276.8, 1e-3, "-inf saturates");
    CHECK_NEAR(t.theta_e_rad, 65535.0 * 9.587379924285257e-05, 1e-5, "u16 saturates high");
    CHECK_NEAR(t.i_d_a, -0.002, 1e-7, "round to nearest, negative");
    CHECK_NEAR(t.i_q_a, -0.004, 1e-7, "round to nearest, negative");
    CHECK(!proto_telem_fast_unpack(&t, buf, PROTO_LEN_TELEM_FAST - 1u), "wrong length refused");
    c.s_abc[0] = 300u;
    c.n_valid = 8u;
    (void)proto_capture_chunk_pack(&c, buf);
    CHECK(buf[55] == 0xFFu, "u8 saturates at 255");
}

/* Frames worked out by hand from docs/protocol.md (the same two as tests/test_codec.py):
 * heartbeat seq 5 counter 0x01020304 and hello seq 0 host_proto_version 2. */
static void test_hand_frames(void)
{
    static const uint16_t hb[] = { 0x09u, 0x09u, 0x05u, 0x04u, 0x03u,
                                   0x02u, 0x01u, 0x80u, 0x47u, 0x00u };
    static const uint16_t hello[] = { 0x02u, 0x01u, 0x02u, 0x02u, 0x03u, 0x94u, 0x16u, 0x00u };
    static const uint16_t hb_payload[] = { 0x04u, 0x03u, 0x02u, 0x01u };
    static const uint16_t hello_payload[] = { 0x02u, 0x00u };
    uint16_t out[16];

    frame_parser_init(&parser);
    CHECK(push_all(&parser, hb, 10u) == 1 && parser.msg_id == 0x09u && parser.seq == 5u &&
              parser.payload_len == 4u && same_octets(parser.payload, hb_payload, 4u),
          "hand heartbeat parses");
    CHECK(push_all(&parser, hello, 8u) == 1 && parser.msg_id == 0x01u && parser.seq == 0u &&
              parser.payload_len == 2u && same_octets(parser.payload, hello_payload, 2u),
          "hand hello parses");
    CHECK(frame_encode(0x09u, 5u, hb_payload, 4u, out, 16u) == 10u && same_octets(out, hb, 10u),
          "heartbeat encodes to the hand frame");
    CHECK(frame_encode(0x01u, 0u, hello_payload, 2u, out, 16u) == 8u && same_octets(out, hello, 8u),
          "hello encodes to the hand frame");
}

int main(void)
{
    test_crc();
    test_hand_frames();
    test_golden_pack_encode();
    test_golden_parse();
    test_bit_flips();
    test_truncation();
    test_errors();
    test_encode_limits();
    test_accessors();
    test_saturation();
    return CHECK_DONE();
}
