/* Event queue of one control period (evq.h). */
#include "evq.h"

#include <stddef.h>

void evq_init(evq_t *q)
{
    q->n = 0u;
    q->lost = 0u;
}

bool evq_push(evq_t *q, uint32_t tick, uint16_t code, int32_t arg)
{
    if (q->n >= EVQ_LEN) {
        q->lost++;
        return false;
    }
    q->e[q->n].tick = tick;
    q->e[q->n].code = code;
    q->e[q->n].arg = arg;
    q->n++;
    return true;
}

uint16_t evq_count(const evq_t *q)
{
    return q->n;
}

const evq_entry_t *evq_at(const evq_t *q, uint16_t i)
{
    return i < q->n ? &q->e[i] : NULL;
}

void evq_clear(evq_t *q)
{
    q->n = 0u;
}
