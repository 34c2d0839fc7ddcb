/* Speed-reference ramp limiter (C28x-safe): the output follows the target at no more than
 * rate_rpm_s; rate 0 (or negative, or not a number) = step. Called once per ts_s. */
#ifndef RAMP_H
#define RAMP_H

typedef struct {
    float rate_rpm_s; /* slew limit, rpm/s (0 = step) */
    float ts_s;       /* call period */
} ramp_cfg_t;

typedef struct {
    ramp_cfg_t cfg;
    float out_rpm;
} ramp_t;

void ramp_init(ramp_t *r, const ramp_cfg_t *cfg); /* output starts at 0 */
float ramp_step(ramp_t *r, float target_rpm);     /* returns the limited reference */
void ramp_reset(ramp_t *r, float out_rpm);        /* jump to a value (e.g. the measured speed) */
void ramp_set_rate(ramp_t *r, float rate_rpm_s);  /* e.g. per profile segment */
#endif
