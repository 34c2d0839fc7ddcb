/* CAN link of the firmware: protocol messages <-> classic CAN frames (docs/can.md).
 *
 * TX: a message becomes 1..n frames in a queue of frames that the board's CAN controller drains
 * (eCAN mailboxes on the F28335, the sim board's bus model in the emulator); a message that does
 * not fit whole is dropped whole (counted by the caller), never cut.
 * RX: frames are reassembled into the same (msg_id, seq, payload) that the serial parser yields.
 * Direct messages: frame k of a message uses function base + k, frame 0 starts with seq, each frame
 * has a fixed length. Transfers: header [0, msg_id, seq, len, crc_hi, crc_lo], then data frames
 * [index 1.., up to 7 octets]; CRC-16/CCITT-FALSE over msg_id, seq, payload. A missing, repeated or
 * misplaced frame, a wrong length or CRC rejects the whole message; a new header or frame 0 starts
 * over (the host retries: commands are acknowledged, capture chunks re-requested).
 * Octets are held one per uint16_t. C28x-safe C99: no globals, no allocation, no clock. */
#ifndef CAN_LINK_H
#define CAN_LINK_H

#include <stdint.h>
#include <stdbool.h>

#include "proto_gen.h"
#include "proto_can_gen.h"

#define CAN_TXQ_FRAMES 64u /* frames; a power of two (the longest transfer needs 1 + 250/7) */

/* can_link_rx results */
#define CAN_RX_NONE        0 /* frame taken (or not for this node / direction): nothing complete */
#define CAN_RX_MSG         1 /* a whole message: msg_id, seq, payload, payload_len are valid */
#define CAN_RX_ERR_UNKNOWN (-1) /* no message uses this function code */
#define CAN_RX_ERR_LEN (-2) /* a frame with the wrong length, or a transfer of the wrong length */
/* a frame missing, repeated or out of place: the message is dropped */
#define CAN_RX_ERR_ORDER (-3)
#define CAN_RX_ERR_CRC   (-4) /* a transfer whose CRC does not match */

typedef struct {
    uint16_t id;  /* 11-bit identifier */
    uint16_t dlc; /* 0..8 */
    uint16_t data[8];
} can_frame_t;

typedef struct {
    uint16_t node; /* 0..15 */
    /* TX queue of frames */
    can_frame_t q[CAN_TXQ_FRAMES];
    uint16_t head, tail, level;
    uint16_t tx_scratch[PROTO_MAX_PAYLOAD + 2u];
    /* RX: direct message being assembled */
    uint16_t rx_msg;  /* 0xFFFF: none */
    uint16_t rx_next; /* next frame index */
    uint16_t rx_n;    /* octets of payload so far */
    /* RX: transfer being assembled; x_buf = msg_id, seq, payload (the CRC's input) */
    bool x_active;
    uint16_t x_len, x_got, x_next, x_crc;
    uint16_t x_buf[PROTO_MAX_PAYLOAD + 2u];
    /* the last whole message (valid after CAN_RX_MSG until the next can_link_rx) */
    uint16_t msg_id;
    uint16_t seq;
    const uint16_t *payload;
    uint16_t payload_len;
    uint16_t rx_buf[PROTO_MAX_PAYLOAD + 2u];
    /* statistics */
    uint32_t msgs_ok;
    uint32_t err_unknown, err_len, err_order, err_crc;
} can_link_t;

void can_link_init(can_link_t *c, uint16_t node);
/* Queues msg_id as frames; false (nothing queued) when it does not fit or the id is unknown. */
bool can_link_send(can_link_t *c, uint16_t msg_id, uint16_t seq, const uint16_t *payload,
                   uint16_t n);
uint16_t can_link_tx_level(const can_link_t *c);          /* frames queued */
const can_frame_t *can_link_tx_peek(const can_link_t *c); /* next frame to send, or 0 */
bool can_link_tx_pop(can_link_t *c, can_frame_t *out);
/* One received frame (data: dlc octets). See CAN_RX_x. */
int16_t can_link_rx(can_link_t *c, uint16_t id, const uint16_t *data, uint16_t dlc);

#endif
