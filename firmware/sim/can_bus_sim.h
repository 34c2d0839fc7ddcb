/* The sim board's CAN controller: sends the firmware's queued frames at the bus bit rate in device
 * time. Each frame costs its real length on the bus: 47 bits of frame + 8 per data octet, the
 * stuff bits of its actual content (so the timing is deterministic), and the 3-bit intermission.
 * Frames wait in the firmware's queue (can_link_t); when that is full the firmware drops whole
 * messages and counts them (status.tx_dropped), as it would with the eCAN mailboxes full. */
#ifndef CAN_BUS_SIM_H
#define CAN_BUS_SIM_H

#include <stdint.h>

#include "fw.h"

#define CAN_SIM_OUT 4096u /* frames sent and not yet taken by the emulator */

typedef struct {
    double bitrate;
    double budget; /* bits the bus has carried towards the frame in progress */
    uint32_t n_out;
    uint16_t out_id[CAN_SIM_OUT];
    uint8_t out_dlc[CAN_SIM_OUT];
    uint8_t out_data[CAN_SIM_OUT][8];
    uint32_t out_isr[CAN_SIM_OUT]; /* control period at the end of the frame */
    double bits_sent;              /* statistics since init, stuff bits included */
    uint32_t frames_sent;
} can_sim_t;

/* Bits of a classic base-format data frame on the bus, stuff bits and intermission included. */
uint32_t can_frame_bits(uint16_t id, const uint16_t *data, uint16_t dlc);
void can_sim_init(can_sim_t *s, double bitrate);
int can_sim_room(const can_sim_t *s);                    /* room for one more period's frames */
void can_sim_period(can_sim_t *s, fw_t *f, double ts_s); /* one control period of bus time */
void can_sim_flush(can_sim_t *s, fw_t *f); /* idle firmware: queued frames leave now */
/* Moves up to cap sent frames out: ids, dlc, data (8 per frame), isr; returns how many. */
uint32_t can_sim_take(can_sim_t *s, uint32_t *ids, uint8_t *dlc, uint8_t *data, uint32_t *isr,
                      uint32_t cap);

#endif
