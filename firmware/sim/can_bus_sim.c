#include "can_bus_sim.h"

#include <string.h>

uint32_t can_frame_bits(uint16_t id, const uint16_t *data, uint16_t dlc)
{
    /* the stuffed part: SOF, identifier, RTR, IDE, r0, DLC, data, CRC-15 */
    uint8_t bits[19 + 64 + 15];
    uint32_t n = 0u, i, stuff = 0u, run = 0u;
    uint16_t crc = 0u, k;
    int b;
    uint8_t last = 2u;
    bits[n++] = 0u;
    for (b = 10; b >= 0; b--) {
        bits[n++] = (uint8_t)((id >> b) & 1u);
    }
    bits[n++] = 0u;
    bits[n++] = 0u;
    bits[n++] = 0u;
    for (b = 3; b >= 0; b--) {
        bits[n++] = (uint8_t)((dlc >> b) & 1u);
    }
    for (k = 0u; k < dlc; k++) {
        for (b = 7; b >= 0; b--) {
            bits[n++] = (uint8_t)((data[k] >> b) & 1u);
        }
    }
    for (i = 0u; i < n; i++) { /* CRC-15/CAN, polynomial 0x4599 */
        uint16_t nxt = (uint16_t)(bits[i] ^ ((crc >> 14) & 1u));
        crc = (uint16_t)((crc << 1) & 0x7FFFu);
        if (nxt) {
            crc ^= 0x4599u;
        }
    }
    for (b = 14; b >= 0; b--) {
        bits[n++] = (uint8_t)((crc >> b) & 1u);
    }
    for (i = 0u; i < n; i++) { /* a stuff bit after five equal bits; it counts in the next run */
        if (bits[i] == last) {
            run++;
        } else {
            last = bits[i];
            run = 1u;
        }
        if (run == 5u) {
            stuff++;
            last = (uint8_t)(1u - last);
            run = 1u;
        }
    }
    /* + CRC delimiter, ACK slot, ACK delimiter, 7 EOF, 3 intermission */
    return n + stuff + 13u;
}

void can_sim_init(can_sim_t *s, double bitrate)
{
    memset(s, 0, sizeof(*s));
    s->bitrate = bitrate;
}

int can_sim_room(const can_sim_t *s)
{
    return s->n_out + 64u <= CAN_SIM_OUT;
}

static void put_out(can_sim_t *s, const can_frame_t *fr, uint32_t isr, uint32_t bits)
{
    uint16_t k;
    if (s->n_out >= CAN_SIM_OUT) {
        return;
    }
    s->out_id[s->n_out] = fr->id;
    s->out_dlc[s->n_out] = (uint8_t)fr->dlc;
    for (k = 0u; k < 8u; k++) {
        s->out_data[s->n_out][k] = (uint8_t)(k < fr->dlc ? fr->data[k] : 0u);
    }
    s->out_isr[s->n_out] = isr;
    s->n_out++;
    s->bits_sent += (double)bits;
    s->frames_sent++;
}

void can_sim_period(can_sim_t *s, fw_t *f, double ts_s)
{
    const can_frame_t *next = can_link_tx_peek(fw_can(f));
    if (next == 0) {
        s->budget = 0.0; /* the bus was idle: no credit carries over */
        return;
    }
    s->budget += s->bitrate * ts_s;
    while (next != 0 && s->n_out < CAN_SIM_OUT) {
        uint32_t bits = can_frame_bits(next->id, next->data, next->dlc);
        can_frame_t fr;
        if (s->budget < (double)bits) {
            return;
        }
        s->budget -= (double)bits;
        (void)can_link_tx_pop(fw_can(f), &fr);
        put_out(s, &fr, fw_isr_count(f), bits);
        next = can_link_tx_peek(fw_can(f));
    }
    if (next == 0) {
        s->budget = 0.0;
    }
}

void can_sim_flush(can_sim_t *s, fw_t *f)
{
    can_frame_t fr;
    while (s->n_out < CAN_SIM_OUT && can_link_tx_pop(fw_can(f), &fr)) {
        put_out(s, &fr, fw_isr_count(f), can_frame_bits(fr.id, fr.data, fr.dlc));
    }
    s->budget = 0.0;
}

uint32_t can_sim_take(can_sim_t *s, uint32_t *ids, uint8_t *dlc, uint8_t *data, uint32_t *isr,
                      uint32_t cap)
{
    uint32_t n = s->n_out < cap ? s->n_out : cap, i;
    for (i = 0u; i < n; i++) {
        ids[i] = s->out_id[i];
        dlc[i] = s->out_dlc[i];
        memcpy(&data[8u * i], s->out_data[i], 8u);
        isr[i] = s->out_isr[i];
    }
    if (n < s->n_out) {
        memmove(s->out_id, s->out_id + n, (s->n_out - n) * sizeof(s->out_id[0]));
        memmove(s->out_dlc, s->out_dlc + n, (s->n_out - n) * sizeof(s->out_dlc[0]));
        memmove(s->out_data, s->out_data + n, (s->n_out - n) * sizeof(s->out_data[0]));
        memmove(s->out_isr, s->out_isr + n, (s->n_out - n) * sizeof(s->out_isr[0]));
    }
    s->n_out -= n;
    return n;
}
