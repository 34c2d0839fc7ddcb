/* Serial framing: frame = COBS(id, seq, payload..., crc_hi, crc_lo) 0x00 (docs/protocol.md).
 *
 * CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final xor) over id, seq and payload,
 * sent high octet first. Octets are held one per uint16_t (values 0..255): the C28x has no 8-bit type.
 * C28x-safe C99: no globals, no allocation; the parser is an object owned by the caller. */
#ifndef FRAME_H
#define FRAME_H

#include <stdint.h>
#include <stdbool.h>

#include "proto_gen.h"

#define FRAME_CRC_INIT    0xFFFFu
#define FRAME_MAX_RAW     (PROTO_MAX_PAYLOAD + 4u) /* id, seq, payload, crc_hi, crc_lo */
#define FRAME_MAX_ENCODED (FRAME_MAX_RAW + FRAME_MAX_RAW / 254u + 2u) /* + COBS codes + 0x00 */

/* frame_parser_push results */
#define FRAME_NONE     0    /* nothing complete yet (or an empty frame between two 0x00) */
#define FRAME_OK       1    /* a good frame: msg_id, seq, payload, payload_len are valid */
#define FRAME_ERR_CRC  (-1) /* CRC mismatch */
#define FRAME_ERR_COBS (-2) /* the frame ended inside a COBS block */
/* FRAME_ERR_LEN: over FRAME_MAX_RAW octets (skipped up to the next 0x00), or a known message id
 * with a payload length other than PROTO_LEN_x */
#define FRAME_ERR_LEN   (-3)
#define FRAME_ERR_SHORT (-4) /* fewer than 4 decoded octets (id, seq, crc) */

/* CRC-16/CCITT-FALSE of n octets (check value: "123456789" -> 0x29B1). */
uint16_t frame_crc16(const uint16_t *d, uint16_t n);

/* Writes COBS(msg_id, seq, payload[0..n), crc_hi, crc_lo) and the 0x00 delimiter to out.
 * Returns the octets written, or 0 when n > PROTO_MAX_PAYLOAD or the frame does not fit in out_cap
 * (FRAME_MAX_ENCODED always fits). msg_id and seq are taken modulo 256. */
uint16_t frame_encode(uint16_t msg_id, uint16_t seq, const uint16_t *payload, uint16_t n,
                      uint16_t *out, uint16_t out_cap);

typedef struct {
    /* decoder state */
    uint16_t buf[FRAME_MAX_RAW]; /* decoded octets of the current frame */
    uint16_t len;                /* decoded octets so far */
    uint16_t block_code;         /* COBS code of the current block; 0 before the first one */
    uint16_t block_left; /* data octets left in the current block; 0: next octet is a code */
    uint16_t crc;        /* running CRC over buf[0..len) */
    bool skipping;       /* after an overflow: ignore octets up to the next 0x00 */
    /* the last good frame: valid after FRAME_OK until the next push */
    uint16_t msg_id;
    uint16_t seq;
    const uint16_t *payload; /* points into buf */
    uint16_t payload_len;
    /* statistics since init */
    uint32_t frames_ok;
    uint32_t frames_bad; /* err_crc + err_cobs + err_len + err_short */
    uint32_t err_crc;
    uint32_t err_cobs;
    uint32_t err_len;
    uint32_t err_short;
} frame_parser_t;

void frame_parser_init(frame_parser_t *p);

/* Feeds one octet; returns FRAME_NONE, FRAME_OK or a FRAME_ERR_x (< 0). A frame is judged when its
 * 0x00 delimiter arrives (an overflow as soon as it happens); after any error the parser
 * resynchronises at the next 0x00. FRAME_OK means: COBS and CRC good and, for a message id the
 * protocol knows, payload_len == PROTO_LEN_x (unknown ids pass, for the dispatcher to refuse). */
int16_t frame_parser_push(frame_parser_t *p, uint16_t octet);

/* sizeof(frame_parser_t), for callers that hold the parser as opaque memory (ctypes). */
uint16_t frame_parser_size(void);

/* Copies the last good frame as (msg_id, seq, payload...) into out; returns 2 + payload_len, or 0 if it
 * does not fit in out_cap. For callers that cannot read the struct (ctypes). */
uint16_t frame_parser_frame(const frame_parser_t *p, uint16_t *out, uint16_t out_cap);

#endif
