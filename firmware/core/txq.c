#include "txq.h"

#include <string.h>

void txq_init(txq_t *q)
{
    q->head = 0u;
    q->tail = 0u;
    q->level = 0u;
    q->dropped = 0u;
}

uint16_t txq_free(const txq_t *q)
{
    return (uint16_t)(TXQ_SIZE - q->level);
}

bool txq_push(txq_t *q, const uint16_t *octets, uint16_t n)
{
    uint16_t first;
    if (n > txq_free(q)) {
        q->dropped++;
        return false;
    }
    /* at most two contiguous pieces: up to the end of the ring, then from its start */
    first = (uint16_t)(TXQ_SIZE - q->head);
    if (first > n) {
        first = n;
    }
    memcpy(&q->buf[q->head], octets, (size_t)first * sizeof(uint16_t));
    memcpy(&q->buf[0], &octets[first], (size_t)(n - first) * sizeof(uint16_t));
    q->head = (uint16_t)((q->head + n) & (TXQ_SIZE - 1u));
    q->level = (uint16_t)(q->level + n);
    return true;
}

bool txq_pop(txq_t *q, uint16_t *octet)
{
    if (q->level == 0u) {
        return false;
    }
    *octet = q->buf[q->tail];
    q->tail = (uint16_t)((q->tail + 1u) & (TXQ_SIZE - 1u));
    q->level = (uint16_t)(q->level - 1u);
    return true;
}

uint16_t txq_pop_n(txq_t *q, uint16_t *out, uint16_t max)
{
    uint16_t n = (q->level < max) ? q->level : max;
    uint16_t i, t = q->tail;
    for (i = 0u; i < n; i++) {
        out[i] = q->buf[t];
        t = (uint16_t)((t + 1u) & (TXQ_SIZE - 1u));
    }
    q->tail = t;
    q->level = (uint16_t)(q->level - n);
    return n;
}
