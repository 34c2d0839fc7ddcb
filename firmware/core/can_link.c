#include "can_link.h"

#include "frame.h"

#define CAN_NONE      0xFFFFu
#define CAN_NODE_MASK ((1u << PROTO_CAN_NODE_BITS) - 1u)

void can_link_init(can_link_t *c, uint16_t node)
{
    uint16_t i;
    c->node = (uint16_t)(node & CAN_NODE_MASK);
    c->head = 0u;
    c->tail = 0u;
    c->level = 0u;
    c->rx_msg = CAN_NONE;
    c->rx_next = 0u;
    c->rx_n = 0u;
    c->rx_crc = 0u;
    c->x_active = false;
    c->x_len = 0u;
    c->x_got = 0u;
    c->x_next = 0u;
    c->x_crc = 0u;
    c->msg_id = 0u;
    c->seq = 0u;
    c->payload = c->rx_buf;
    c->payload_len = 0u;
    c->msgs_ok = 0u;
    c->err_unknown = 0u;
    c->err_len = 0u;
    c->err_order = 0u;
    c->err_crc = 0u;
    for (i = 0u; i < CAN_TXQ_FRAMES; i++) {
        c->q[i].id = 0u;
        c->q[i].dlc = 0u;
    }
}

/* ------------------------------------------------------------------ TX */

static can_frame_t *tx_slot(can_link_t *c, uint16_t func, uint16_t dlc)
{
    can_frame_t *fr = &c->q[c->head];
    c->head = (uint16_t)((c->head + 1u) & (CAN_TXQ_FRAMES - 1u));
    c->level++;
    fr->id = (uint16_t)((func << PROTO_CAN_NODE_BITS) | c->node);
    fr->dlc = dlc;
    return fr;
}

bool can_link_send(can_link_t *c, uint16_t msg_id, uint16_t seq, const uint16_t *payload,
                   uint16_t n)
{
    proto_can_layout_t l;
    uint16_t k, i, at = 0u;
    if (!proto_can_layout(msg_id, &l) || n > PROTO_MAX_PAYLOAD) {
        return false;
    }
    if (l.transfer != 0u) {
        uint16_t frames =
            (uint16_t)(1u + (n + PROTO_CAN_TRANSFER_DATA - 1u) / PROTO_CAN_TRANSFER_DATA);
        uint16_t crc;
        can_frame_t *fr;
        if (frames > (uint16_t)(CAN_TXQ_FRAMES - c->level)) {
            return false;
        }
        c->tx_scratch[0] = (uint16_t)(msg_id & 0xFFu);
        c->tx_scratch[1] = (uint16_t)(seq & 0xFFu);
        for (i = 0u; i < n; i++) {
            c->tx_scratch[2u + i] = (uint16_t)(payload[i] & 0xFFu);
        }
        crc = frame_crc16(c->tx_scratch, (uint16_t)(n + 2u));
        fr = tx_slot(c, l.func, PROTO_CAN_TRANSFER_HEADER);
        fr->data[0] = 0u;
        fr->data[1] = c->tx_scratch[0];
        fr->data[2] = c->tx_scratch[1];
        fr->data[3] = n;
        fr->data[4] = (uint16_t)(crc >> 8);
        fr->data[5] = (uint16_t)(crc & 0xFFu);
        for (k = 1u; k < frames; k++) {
            uint16_t m = (uint16_t)(n - at);
            if (m > PROTO_CAN_TRANSFER_DATA) {
                m = PROTO_CAN_TRANSFER_DATA;
            }
            fr = tx_slot(c, l.func, (uint16_t)(m + 1u));
            fr->data[0] = k;
            for (i = 0u; i < m; i++) {
                fr->data[1u + i] = c->tx_scratch[2u + at + i];
            }
            at = (uint16_t)(at + m);
        }
        return true;
    }
    {
        uint16_t total = 0u, crc = 0u;
        bool has_crc = l.crc_frame != PROTO_CAN_NO_CRC;
        for (k = 0u; k < l.n_frames; k++) {
            total = (uint16_t)(total + l.len[k]);
        }
        if (has_crc) {
            total = (uint16_t)(total - PROTO_CAN_CRC_OCTETS);
        }
        if (total != (uint16_t)(n + 1u) || l.n_frames > (uint16_t)(CAN_TXQ_FRAMES - c->level)) {
            return false;
        }
        if (has_crc) { /* the end-to-end check: the serial frame's CRC */
            c->tx_scratch[0] = (uint16_t)(msg_id & 0xFFu);
            c->tx_scratch[1] = (uint16_t)(seq & 0xFFu);
            for (i = 0u; i < n; i++) {
                c->tx_scratch[2u + i] = (uint16_t)(payload[i] & 0xFFu);
            }
            crc = frame_crc16(c->tx_scratch, (uint16_t)(n + 2u));
        }
        for (k = 0u; k < l.n_frames; k++) {
            can_frame_t *fr = tx_slot(c, (uint16_t)(l.func + k), l.len[k]);
            uint16_t end = l.len[k];
            if (k == l.crc_frame) {
                end = (uint16_t)(end - PROTO_CAN_CRC_OCTETS);
                fr->data[end] = (uint16_t)(crc >> 8);
                fr->data[end + 1u] = (uint16_t)(crc & 0xFFu);
            }
            i = 0u;
            if (k == 0u) {
                fr->data[0] = (uint16_t)(seq & 0xFFu);
                i = 1u;
            }
            for (; i < end; i++) {
                fr->data[i] = (uint16_t)(payload[at++] & 0xFFu);
            }
        }
        return true;
    }
}

uint16_t can_link_tx_level(const can_link_t *c)
{
    return c->level;
}

const can_frame_t *can_link_tx_peek(const can_link_t *c)
{
    return c->level == 0u ? (const can_frame_t *)0 : &c->q[c->tail];
}

bool can_link_tx_pop(can_link_t *c, can_frame_t *out)
{
    if (c->level == 0u) {
        return false;
    }
    *out = c->q[c->tail];
    c->tail = (uint16_t)((c->tail + 1u) & (CAN_TXQ_FRAMES - 1u));
    c->level--;
    return true;
}

/* ------------------------------------------------------------------ RX */

static int16_t rx_error(can_link_t *c, int16_t err)
{
    c->rx_msg = CAN_NONE;
    c->x_active = false;
    switch (err) {
    case CAN_RX_ERR_UNKNOWN:
        c->err_unknown++;
        break;
    case CAN_RX_ERR_LEN:
        c->err_len++;
        break;
    case CAN_RX_ERR_CRC:
        c->err_crc++;
        break;
    default:
        c->err_order++;
        break;
    }
    return err;
}

static int16_t rx_done(can_link_t *c, uint16_t msg_id, uint16_t seq, const uint16_t *p, uint16_t n)
{
    c->msg_id = msg_id;
    c->seq = seq;
    c->payload = p;
    c->payload_len = n;
    c->msgs_ok++;
    return CAN_RX_MSG;
}

static int16_t rx_transfer(can_link_t *c, const uint16_t *data, uint16_t dlc)
{
    uint16_t i, m;
    if (dlc == 0u) {
        return rx_error(c, CAN_RX_ERR_LEN);
    }
    if ((data[0] & 0xFFu) == 0u) { /* header: a new transfer (an unfinished one is dropped) */
        int16_t len;
        bool stale = c->x_active;
        if (dlc != PROTO_CAN_TRANSFER_HEADER || data[3] > PROTO_MAX_PAYLOAD) {
            return rx_error(c, CAN_RX_ERR_LEN);
        }
        len = proto_payload_len(data[1]);
        if (len >= 0 && (uint16_t)len != data[3]) {
            return rx_error(c, CAN_RX_ERR_LEN);
        }
        if (stale) {
            (void)rx_error(c, CAN_RX_ERR_ORDER);
        }
        c->x_active = true;
        c->x_buf[0] = (uint16_t)(data[1] & 0xFFu);
        c->x_buf[1] = (uint16_t)(data[2] & 0xFFu);
        c->x_len = data[3];
        c->x_crc = (uint16_t)(((data[4] & 0xFFu) << 8) | (data[5] & 0xFFu));
        c->x_got = 0u;
        c->x_next = 1u;
    } else {
        if (!c->x_active || (data[0] & 0xFFu) != c->x_next) {
            return rx_error(c, CAN_RX_ERR_ORDER);
        }
        m = (uint16_t)(c->x_len - c->x_got);
        if (m > PROTO_CAN_TRANSFER_DATA) {
            m = PROTO_CAN_TRANSFER_DATA;
        }
        if (dlc != (uint16_t)(m + 1u)) {
            return rx_error(c, CAN_RX_ERR_LEN);
        }
        for (i = 0u; i < m; i++) {
            c->x_buf[2u + c->x_got + i] = (uint16_t)(data[1u + i] & 0xFFu);
        }
        c->x_got = (uint16_t)(c->x_got + m);
        c->x_next++;
    }
    if (c->x_got < c->x_len) {
        return CAN_RX_NONE;
    }
    c->x_active = false;
    if (frame_crc16(c->x_buf, (uint16_t)(c->x_len + 2u)) != c->x_crc) {
        return rx_error(c, CAN_RX_ERR_CRC);
    }
    return rx_done(c, c->x_buf[0], c->x_buf[1], &c->x_buf[2], c->x_len);
}

int16_t can_link_rx(can_link_t *c, uint16_t id, const uint16_t *data, uint16_t dlc)
{
    uint16_t func = (uint16_t)((id >> PROTO_CAN_NODE_BITS) & 0x7Fu);
    uint16_t k, i, start, end;
    int16_t msg;
    proto_can_layout_t l;
    if ((id & CAN_NODE_MASK) != c->node || dlc > 8u) {
        return CAN_RX_NONE;
    }
    if (func == PROTO_CAN_FUNC_TRANSFER_H2D) {
        return rx_transfer(c, data, dlc);
    }
    msg = proto_can_func_msg(func, &k);
    if (msg < 0) {
        return func == PROTO_CAN_FUNC_TRANSFER_D2H ? CAN_RX_NONE : rx_error(c, CAN_RX_ERR_UNKNOWN);
    }
    (void)proto_can_layout((uint16_t)msg, &l);
    if (l.h2d == 0u) {
        return CAN_RX_NONE; /* another device's frame */
    }
    if (dlc != l.len[k]) {
        return rx_error(c, CAN_RX_ERR_LEN);
    }
    if (k == 0u) {
        if (c->rx_msg != CAN_NONE) {
            (void)rx_error(c, CAN_RX_ERR_ORDER); /* the unfinished one is dropped */
        }
        c->rx_msg = (uint16_t)msg;
        c->rx_next = 0u;
        c->rx_n = 0u;
        c->rx_buf[0] = (uint16_t)msg; /* msg_id, seq in front of the payload: the CRC's input */
        c->rx_buf[1] = (uint16_t)(data[0] & 0xFFu);
        start = 1u;
    } else {
        if (c->rx_msg != (uint16_t)msg || c->rx_next != k) {
            return rx_error(c, CAN_RX_ERR_ORDER);
        }
        start = 0u;
    }
    end = dlc;
    if (k == l.crc_frame) {
        end = (uint16_t)(dlc - PROTO_CAN_CRC_OCTETS);
        c->rx_crc = (uint16_t)(((data[end] & 0xFFu) << 8) | (data[end + 1u] & 0xFFu));
    }
    for (i = start; i < end; i++) {
        c->rx_buf[2u + c->rx_n] = (uint16_t)(data[i] & 0xFFu);
        c->rx_n++;
    }
    c->rx_next = (uint16_t)(k + 1u);
    if (c->rx_next < l.n_frames) {
        return CAN_RX_NONE;
    }
    c->rx_msg = CAN_NONE;
    if (l.crc_frame != PROTO_CAN_NO_CRC) {
        /* end to end: frames of two messages joined after a lost burst do not pass */
        if (frame_crc16(c->rx_buf, (uint16_t)(c->rx_n + 2u)) != c->rx_crc) {
            return rx_error(c, CAN_RX_ERR_CRC);
        }
    }
    return rx_done(c, (uint16_t)msg, c->rx_buf[1], &c->rx_buf[2], c->rx_n);
}
