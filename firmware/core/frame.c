/* Serial framing: CRC-16/CCITT-FALSE, COBS encoder and incremental decoder (see frame.h). */
#include "frame.h"

#include <string.h>

/* CRC-16/CCITT-FALSE (polynomial 0x1021) of one octet from a zero register: crc16_step()'s table. */
static const uint16_t k_crc_tab[256] = {
    0x0000u, 0x1021u, 0x2042u, 0x3063u, 0x4084u, 0x50A5u, 0x60C6u, 0x70E7u, 0x8108u, 0x9129u,
    0xA14Au, 0xB16Bu, 0xC18Cu, 0xD1ADu, 0xE1CEu, 0xF1EFu, 0x1231u, 0x0210u, 0x3273u, 0x2252u,
    0x52B5u, 0x4294u, 0x72F7u, 0x62D6u, 0x9339u, 0x8318u, 0xB37Bu, 0xA35Au, 0xD3BDu, 0xC39Cu,
    0xF3FFu, 0xE3DEu, 0x2462u, 0x3443u, 0x0420u, 0x1401u, 0x64E6u, 0x74C7u, 0x44A4u, 0x5485u,
    0xA56Au, 0xB54Bu, 0x8528u, 0x9509u, 0xE5EEu, 0xF5CFu, 0xC5ACu, 0xD58Du, 0x3653u, 0x2672u,
    0x1611u, 0x0630u, 0x76D7u, 0x66F6u, 0x5695u, 0x46B4u, 0xB75Bu, 0xA77Au, 0x9719u, 0x8738u,
    0xF7DFu, 0xE7FEu, 0xD79Du, 0xC7BCu, 0x48C4u, 0x58E5u, 0x6886u, 0x78A7u, 0x0840u, 0x1861u,
    0x2802u, 0x3823u, 0xC9CCu, 0xD9EDu, 0xE98Eu, 0xF9AFu, 0x8948u, 0x9969u, 0xA90Au, 0xB92Bu,
    0x5AF5u, 0x4AD4u, 0x7AB7u, 0x6A96u, 0x1A71u, 0x0A50u, 0x3A33u, 0x2A12u, 0xDBFDu, 0xCBDCu,
    0xFBBFu, 0xEB9Eu, 0x9B79u, 0x8B58u, 0xBB3Bu, 0xAB1Au, 0x6CA6u, 0x7C87u, 0x4CE4u, 0x5CC5u,
    0x2C22u, 0x3C03u, 0x0C60u, 0x1C41u, 0xEDAEu, 0xFD8Fu, 0xCDECu, 0xDDCDu, 0xAD2Au, 0xBD0Bu,
    0x8D68u, 0x9D49u, 0x7E97u, 0x6EB6u, 0x5ED5u, 0x4EF4u, 0x3E13u, 0x2E32u, 0x1E51u, 0x0E70u,
    0xFF9Fu, 0xEFBEu, 0xDFDDu, 0xCFFCu, 0xBF1Bu, 0xAF3Au, 0x9F59u, 0x8F78u, 0x9188u, 0x81A9u,
    0xB1CAu, 0xA1EBu, 0xD10Cu, 0xC12Du, 0xF14Eu, 0xE16Fu, 0x1080u, 0x00A1u, 0x30C2u, 0x20E3u,
    0x5004u, 0x4025u, 0x7046u, 0x6067u, 0x83B9u, 0x9398u, 0xA3FBu, 0xB3DAu, 0xC33Du, 0xD31Cu,
    0xE37Fu, 0xF35Eu, 0x02B1u, 0x1290u, 0x22F3u, 0x32D2u, 0x4235u, 0x5214u, 0x6277u, 0x7256u,
    0xB5EAu, 0xA5CBu, 0x95A8u, 0x8589u, 0xF56Eu, 0xE54Fu, 0xD52Cu, 0xC50Du, 0x34E2u, 0x24C3u,
    0x14A0u, 0x0481u, 0x7466u, 0x6447u, 0x5424u, 0x4405u, 0xA7DBu, 0xB7FAu, 0x8799u, 0x97B8u,
    0xE75Fu, 0xF77Eu, 0xC71Du, 0xD73Cu, 0x26D3u, 0x36F2u, 0x0691u, 0x16B0u, 0x6657u, 0x7676u,
    0x4615u, 0x5634u, 0xD94Cu, 0xC96Du, 0xF90Eu, 0xE92Fu, 0x99C8u, 0x89E9u, 0xB98Au, 0xA9ABu,
    0x5844u, 0x4865u, 0x7806u, 0x6827u, 0x18C0u, 0x08E1u, 0x3882u, 0x28A3u, 0xCB7Du, 0xDB5Cu,
    0xEB3Fu, 0xFB1Eu, 0x8BF9u, 0x9BD8u, 0xABBBu, 0xBB9Au, 0x4A75u, 0x5A54u, 0x6A37u, 0x7A16u,
    0x0AF1u, 0x1AD0u, 0x2AB3u, 0x3A92u, 0xFD2Eu, 0xED0Fu, 0xDD6Cu, 0xCD4Du, 0xBDAAu, 0xAD8Bu,
    0x9DE8u, 0x8DC9u, 0x7C26u, 0x6C07u, 0x5C64u, 0x4C45u, 0x3CA2u, 0x2C83u, 0x1CE0u, 0x0CC1u,
    0xEF1Fu, 0xFF3Eu, 0xCF5Du, 0xDF7Cu, 0xAF9Bu, 0xBFBAu, 0x8FD9u, 0x9FF8u, 0x6E17u, 0x7E36u,
    0x4E55u, 0x5E74u, 0x2E93u, 0x3EB2u, 0x0ED1u, 0x1EF0u
};

/* One octet of CRC-16/CCITT-FALSE. */
static inline uint16_t crc16_step(uint16_t crc, uint16_t octet)
{
    return (uint16_t)((uint16_t)(crc << 8) ^ k_crc_tab[((crc >> 8) ^ octet) & 0xFFu]);
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

/* COBS encoder state of frame_encode's single pass (the output is known to fit). */
typedef struct {
    uint16_t *out;
    uint16_t o;        /* next output position */
    uint16_t code_pos; /* where the current block's code goes */
    uint16_t code;     /* 1 + data octets in the current block */
} cobs_enc_t;

/* One raw octet that is not the frame's last. */
static inline void cobs_put(cobs_enc_t *e, uint16_t b)
{
    if (b != 0u) {
        e->out[e->o] = b;
        e->o++;
        e->code++;
        if (e->code != 0xFFu) {
            return;
        }
    }
    e->out[e->code_pos] = e->code;
    e->code_pos = e->o;
    e->o++;
    e->code = 1u;
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
    raw_len = (uint16_t)(n + 4u);

    if (out_cap >= raw_len + raw_len / 254u + 2u) {
        /* fits whatever the data (at most one code octet per 254 data octets, plus the first code
         * and the delimiter): one pass, CRC and COBS together, no bounds checks */
        cobs_enc_t e;
        uint16_t b;
        e.out = out;
        e.o = 1u;
        e.code_pos = 0u;
        e.code = 1u;
        crc = crc16_step(FRAME_CRC_INIT, msg_id);
        cobs_put(&e, msg_id);
        crc = crc16_step(crc, seq);
        cobs_put(&e, seq);
        for (i = 0u; i < n; i++) {
            b = (uint16_t)(payload[i] & 0xFFu);
            crc = crc16_step(crc, b);
            cobs_put(&e, b);
        }
        cobs_put(&e, (uint16_t)(crc >> 8));
        b = (uint16_t)(crc & 0xFFu); /* the last raw octet */
        if (b != 0u) {
            out[e.o] = b;
            e.o++;
            e.code++;
            out[e.code_pos] =
                e.code; /* a full block (code 0xFF) ends the data: no further code octet */
        } else {
            out[e.code_pos] = e.code;
            out[e.o] = 1u;
            e.o++;
        }
        out[e.o] = 0u;
        return (uint16_t)(e.o + 1u);
    }

    /* small output buffer: octet by octet with bounds checks (0 if it does not fit) */
    crc = crc16_step(crc16_step(FRAME_CRC_INIT, msg_id), seq);
    for (i = 0u; i < n; i++) {
        crc = crc16_step(crc, (uint16_t)(payload[i] & 0xFFu));
    }
    code_pos = 0u; /* where the current block's code goes */
    o = 1u;        /* next output position */
    code = 1u;     /* 1 + data octets in the current block */
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
                code_pos = 0xFFFFu; /* a full block ends the data: no further code octet */
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
    case FRAME_ERR_CRC:
        p->err_crc++;
        break;
    case FRAME_ERR_COBS:
        p->err_cobs++;
        break;
    case FRAME_ERR_LEN:
        p->err_len++;
        break;
    default:
        p->err_short++;
        break;
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
    bool crc_ok = (p->crc == 0u); /* CRC over data + its own CRC (high first) leaves 0 */
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
