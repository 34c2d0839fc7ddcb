/* Transmit queue: a ring of octets (one per uint16_t) drained by the board's UART at the link rate.
 * Whole frames are queued or dropped (and counted), never split. */
#ifndef TXQ_H
#define TXQ_H

#include <stdint.h>
#include <stdbool.h>

#define TXQ_SIZE 1024u /* octets; a power of two */

typedef struct {
    uint16_t buf[TXQ_SIZE];
    uint16_t head; /* next write */
    uint16_t tail; /* next read */
    uint16_t level;
    uint32_t dropped; /* frames that did not fit */
} txq_t;

void txq_init(txq_t *q);
uint16_t txq_free(const txq_t *q);
bool txq_push(txq_t *q, const uint16_t *octets,
              uint16_t n); /* false (and counted) if it does not fit */
bool txq_pop(txq_t *q, uint16_t *octet);
uint16_t txq_pop_n(txq_t *q, uint16_t *out, uint16_t max); /* up to max octets; returns how many */

#endif
