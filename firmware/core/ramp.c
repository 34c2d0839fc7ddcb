/* Speed-reference ramp limiter. See ramp.h. */
#include "ramp.h"

void ramp_init(ramp_t *r, const ramp_cfg_t *cfg)
{
    r->cfg = *cfg;
    ramp_set_rate(r, cfg->rate_rpm_s);
    r->out_rpm = 0.0f;
}

void ramp_set_rate(ramp_t *r, float rate_rpm_s)
{
    r->cfg.rate_rpm_s = (rate_rpm_s > 0.0f) ? rate_rpm_s : 0.0f;
}

void ramp_reset(ramp_t *r, float out_rpm)
{
    r->out_rpm = out_rpm;
}

float ramp_step(ramp_t *r, float target_rpm)
{
    const float dmax = r->cfg.rate_rpm_s * r->cfg.ts_s;
    if (!(dmax > 0.0f)) {
        r->out_rpm = target_rpm;
    } else if (target_rpm > r->out_rpm + dmax) {
        r->out_rpm += dmax;
    } else if (target_rpm < r->out_rpm - dmax) {
        r->out_rpm -= dmax;
    } else {
        r->out_rpm = target_rpm;
    }
    return r->out_rpm;
}
