/* Event queue of one control period: the stages raise events while the period runs, the
 * firmware sends them once at its end (no stage calls into the message code). Each entry keeps
 * the tick at which it was raised. A full queue counts what it could not keep. */
#ifndef EVQ_H
#define EVQ_H

#include <stdint.h>
#include <stdbool.h>

#define EVQ_LEN 12u /* more than one period can raise (fault, trigger, stop, segment, done) */

typedef struct {
    uint32_t tick;
    uint16_t code; /* PROTO_EVENT_* */
    int32_t arg;
} evq_entry_t;

typedef struct {
    evq_entry_t e[EVQ_LEN];
    uint16_t n;
    uint32_t lost; /* events raised while the queue was full */
} evq_t;

void evq_init(evq_t *q);
bool evq_push(evq_t *q, uint32_t tick, uint16_t code, int32_t arg);
uint16_t evq_count(const evq_t *q);
const evq_entry_t *evq_at(const evq_t *q, uint16_t i); /* i = 0 is the oldest; NULL past the end */
void evq_clear(evq_t *q);

#endif
