#include "dither.h"

void dither_init(dither_t *d, const dither_cfg_t *cfg)
{
    d->cfg = *cfg;
    if (d->cfg.period < 2u) {
        d->cfg.period = 2u;
    }
    d->k = 0u;
    d->inv_half = 2.0f / (float)d->cfg.period;
}

float dither_step(dither_t *d, float step_a)
{
    float x = (float)d->k * d->inv_half;
    float tri = (x < 1.0f) ? x : 2.0f - x; /* 0 .. 1 .. 0 */
    d->k++;
    if (d->k >= d->cfg.period) {
        d->k = 0u;
    }
    return d->cfg.gain * step_a * (tri - 0.5f);
}
