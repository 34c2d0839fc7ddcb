/* Triangular dither on the q-current reference.
 *
 * A finite-control-set current controller moves the current in steps of one active vector held
 * for one period (here (2/3) v_dc Ts / L_q, about 1.5 A for paper A's motor on 540 V). At light
 * load the current has nothing to decay against, so it sits in that dead band and the speed loop
 * limit-cycles around it. A zero-mean triangle of a fraction of the step, at a period that is not
 * a divisor of the speed loop's, linearises the quantiser as dither does for an ADC: the mean
 * current follows the reference continuously. docs/control.md gives the measurements. */
#ifndef DITHER_H
#define DITHER_H

#include <stdint.h>

typedef struct {
    uint16_t period; /* control periods per triangle (>= 2) */
    float gain;      /* peak-to-peak amplitude as a fraction of the current step (0 disables) */
} dither_cfg_t;

typedef struct {
    dither_cfg_t cfg;
    uint16_t k;
    float inv_half; /* 2 / period */
} dither_t;

void dither_init(dither_t *d, const dither_cfg_t *cfg);
/* The offset for this period, given the current step of one active vector for one period. */
float dither_step(dither_t *d, float step_a);

#endif
