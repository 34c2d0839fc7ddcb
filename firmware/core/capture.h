/* Triggered control-rate capture: a ring buffer of samples in firmware RAM, recording continuously
 * while armed; a trigger keeps `pre` samples from before it and fills the rest after, then freezes
 * until uploaded (capture_chunk) and re-armed. Samples are held in the wire's scaled integers. */
#ifndef CAPTURE_H
#define CAPTURE_H

#include <stdint.h>
#include <stdbool.h>

#define CAPTURE_LEN 1024u /* samples; a power of two (7 words each: 14 KiB on the F28335) */

typedef struct {
    float i_a_a, i_b_a, i_c_a;
    uint16_t s_abc; /* bit0 s_a, bit1 s_b, bit2 s_c */
    float v_dc_v, theta_e_rad, omega_e_rad_s;
} capture_sample_t;

typedef enum {
    CAPTURE_ARMED = 0,
    CAPTURE_TRIGGERED = 1,
    CAPTURE_FROZEN = 2
} capture_state_t;

typedef struct {
    int16_t i_a[CAPTURE_LEN], i_b[CAPTURE_LEN], i_c[CAPTURE_LEN];
    uint16_t s_abc[CAPTURE_LEN];
    int16_t v_dc[CAPTURE_LEN];
    uint16_t theta[CAPTURE_LEN];
    int16_t omega[CAPTURE_LEN];
    uint16_t head;  /* next write */
    uint16_t count; /* valid samples (<= CAPTURE_LEN) */
    uint16_t pre;
    uint16_t post_left;
    uint32_t tick_head; /* tick of the sample at head-1 */
    capture_state_t state;
} capture_t;

void capture_init(capture_t *c, uint16_t pre);
void capture_record(capture_t *c, uint32_t tick, const capture_sample_t *s);
bool capture_trigger(capture_t *c); /* false if a capture is already triggered or frozen */
bool capture_freeze(
    capture_t *c); /* stop now, keeping everything recorded (a fault); false if already frozen */
bool capture_frozen(const capture_t *c);
uint16_t capture_count(const capture_t *c);
uint32_t capture_tick0(const capture_t *c); /* tick of the oldest sample */
bool capture_get(const capture_t *c, uint16_t i, capture_sample_t *s); /* i = 0 is the oldest */
void capture_rearm(capture_t *c);

#endif
