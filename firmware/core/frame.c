/* Serial framing: CRC-16/CCITT-FALSE, COBS encoder and incremental decoder (see frame.h). */
#include "frame.h"

#include <string.h>

/* One octet of CRC-16/CCITT-FALSE, table-free (shift/xor form of the 0x1021 polynomial). */
static uint16_t crc16_step(uint16_t crc, uint16_t octet)
{
    uint16_t x = (uint16_t)(((crc >> 8) ^ octet) & 0xFFu);
    x = (uint16_t)(x ^ (x >> 4));
    return (uint16_t)((uint16_t)(crc << 8) ^ (uint16_t)(x << 12) ^ (uint16_t)(x << 5) ^ x);
}

uint16_t frame_crc16(const uint16_t *d, uint16_t n)
{
    uint16_t crc = FRAME_CRC_INIT;
    uint16_t i;
    for (i = 0u; i < n; i++) {
        crc = crc16_step(crc, (uint16_t)(d[i] & 0xFFu));
    }
    return crc;
}

/* ------------------------------------------------------------------------------------ encoder */

/* Octet i of the raw frame (id, seq, payload..., crc_hi, crc_lo). */
static uint16_t raw_octet(uint16_t i, uint16_t msg_id, uint16_t seq, const uint16_t *payload,
                          uint16_t n, uint16_t crc)
{
    if (i == 0u) {
        return msg_id;
    }
    if (i == 1u) {
        return seq;
    }
    if (i < n + 2u) {
        return (uint16_t)(payload[i - 2u] & 0xFFu);
    }
    return (i == n + 2u) ? (uint16_t)(crc >> 8) : (uint16_t)(crc & 0xFFu);
}

uint16_t frame_encode(uint16_t msg_id, uint16_t seq, const uint16_t *payload, uint16_t n,
                      uint16_t *out, uint16_t out_cap)
{
    uint16_t crc, i, raw_len, code_pos, o, code;

    if (n > PROTO_MAX_PAYLOAD || out_cap < 2u) {
        return 0u;
    }
    msg_id = (uint16_t)(msg_id & 0xFFu);
    seq = (uint16_t)(seq & 0xFFu);
    crc = crc16_step(crc16_step(FRAME_CRC_INIT, msg_id), seq);
    for (i = 0u; i < n; i++) {
        crc = crc16_step(crc, (uint16_t)(payload[i] & 0xFFu));
    }

    raw_len = (uint16_t)(n + 4u);
    code_pos = 0u;      /* where the current block's code goes */
    o = 1u;             /* next output position */
    code = 1u;          /* 1 + data octets in the current block */
    for (i = 0u; i < raw_len; i++) {
        uint16_t b = raw_octet(i, msg_id, seq, payload, n, crc);
        if (b != 0u) {
            if (o >= out_cap) {
                return 0u;
            }
            out[o] = b;
            o++;
            code++;
        }
        if (b == 0u || code == 0xFFu) {
            out[code_pos] = code;
            if (b != 0u && i + 1u == raw_len) {
                code_pos = 0xFFFFu;   /* a full block ends the data: no further code octet */
                break;
            }
            if (o >= out_cap) {
                return 0u;
            }
            code_pos = o;
            o++;
            code = 1u;
        }
    }
    if (code_pos != 0xFFFFu) {
        out[code_pos] = code;
    }
    if (o >= out_cap) {
        return 0u;
    }
    out[o] = 0u;
    return (uint16_t)(o + 1u);
}

/* ------------------------------------------------------------------------------------- parser */

static void parser_restart(frame_parser_t *p)
{
    p->len = 0u;
    p->block_code = 0u;
    p->block_left = 0u;
    p->crc = FRAME_CRC_INIT;
    p->skipping = false;
}

void frame_parser_init(frame_parser_t *p)
{
    memset(p, 0, sizeof(*p));
    parser_restart(p);
    p->payload = &p->buf[2];
}

static int16_t parser_error(frame_parser_t *p, int16_t err)
{
    p->frames_bad++;
    switch (err) {
    case FRAME_ERR_CRC: p->err_crc++; break;
    case FRAME_ERR_COBS: p->err_cobs++; break;
    case FRAME_ERR_LEN: p->err_len++; break;
    default: p->err_short++; break;
    }
    return err;
}

/* Appends a decoded octet; false on overflow. */
static bool parser_append(frame_parser_t *p, uint16_t octet)
{
    if (p->len >= FRAME_MAX_RAW) {
        return false;
    }
    p->buf[p->len] = octet;
    p->len++;
    p->crc = crc16_step(p->crc, octet);
    return true;
}

/* The 0x00 delimiter: judge the frame collected so far. */
static int16_t parser_end(frame_parser_t *p)
{
    bool empty = (p->block_code == 0u);
    bool skipped = p->skipping;
    bool truncated = (p->block_left != 0u);
    bool short_frame = (p->len < 4u);
    bool crc_ok = (p->crc == 0u);   /* CRC over data + its own CRC (high first) leaves 0 */
    int16_t expected_len = short_frame ? -1 : proto_payload_len(p->buf[0]);
    bool len_ok = (expected_len < 0) || ((uint16_t)expected_len + 4u == p->len);
    parser_restart(p);
    if (empty || skipped) {
        return FRAME_NONE;
    }
    if (truncated) {
        return parser_error(p, FRAME_ERR_COBS);
    }
    if (short_frame) {
        return parser_error(p, FRAME_ERR_SHORT);
    }
    if (!crc_ok) {
        return parser_error(p, FRAME_ERR_CRC);
    }
    if (!len_ok) {
        /* CRC-16/CCITT-FALSE cannot see 0x00 octets appended after the CRC (the residue stays 0),
         * which a delimiter flipped to 0x01 produces: the known payload length catches that. */
        return parser_error(p, FRAME_ERR_LEN);
    }
    return FRAME_OK;
}

int16_t frame_parser_push(frame_parser_t *p, uint16_t octet)
{
    octet = (uint16_t)(octet & 0xFFu);
    if (octet == 0u) {
        uint16_t n = p->len;
        int16_t r = parser_end(p);
        if (r == FRAME_OK) {
            p->msg_id = p->buf[0];
            p->seq = p->buf[1];
            p->payload = &p->buf[2];
            p->payload_len = (uint16_t)(n - 4u);
            p->frames_ok++;
        }
        return r;
    }
    if (p->skipping) {
        return FRAME_NONE;
    }
    if (p->block_left == 0u) {
        /* a code octet: the previous block (if any, and if not a full one) ended with a zero */
        if (p->block_code != 0u && p->block_code != 0xFFu && !parser_append(p, 0u)) {
            p->skipping = true;
            return parser_error(p, FRAME_ERR_LEN);
        }
        p->block_code = octet;
        p->block_left = (uint16_t)(octet - 1u);
        return FRAME_NONE;
    }
    p->block_left--;
    if (!parser_append(p, octet)) {
        p->skipping = true;
        return parser_error(p, FRAME_ERR_LEN);
    }
    return FRAME_NONE;
}

uint16_t frame_parser_size(void)
{
    return (uint16_t)sizeof(frame_parser_t);
}

uint16_t frame_parser_frame(const frame_parser_t *p, uint16_t *out, uint16_t out_cap)
{
    uint16_t i;
    if (out_cap < p->payload_len + 2u) {
        return 0u;
    }
    out[0] = p->msg_id;
    out[1] = p->seq;
    for (i = 0u; i < p->payload_len; i++) {
        out[2u + i] = p->payload[i];
    }
    return (uint16_t)(p->payload_len + 2u);
}
