/* Magnet polarity at start-up by d-axis pulses (polarity.h). */
#include "polarity.h"

#include <math.h>
#include <string.h>

static uint32_t ticks_of(float t_s, float ts_s)
{
    float n = t_s / ts_s;
    if (!(n >= 1.0f)) {
        return 1u;
    }
    if (n > 1.0e6f) {
        return 1000000u;
    }
    return (uint32_t)(n + 0.5f);
}

void pol_init(pol_t *p, const pol_cfg_t *cfg)
{
    memset(p, 0, sizeof(*p));
    p->cfg = *cfg;
    p->n_settle = ticks_of(cfg->settle_s, cfg->ts_s);
    p->n_pulse = ticks_of(cfg->pulse_s, cfg->ts_s);
    p->n_release = ticks_of(cfg->release_s, cfg->ts_s);
    p->result = POL_RUNNING;
}

uint16_t pol_decide(const pol_cfg_t *cfg, float g_pos, float g_neg, float *asym)
{
    float a = 0.0f;
    if (g_pos > 0.0f && g_neg > 0.0f) {
        a = (g_pos - g_neg) / (g_pos + g_neg);
    }
    *asym = a;
    if (!(fabsf(a) >= cfg->asym_min) || cfg->asym_expected == 0.0f) {
        return POL_UNRESOLVED;
    }
    return (a > 0.0f) == (cfg->asym_expected > 0.0f) ? POL_KEPT : POL_FLIPPED;
}

void pol_step(pol_t *p, const pol_in_t *in, pol_out_t *out)
{
    const uint32_t t = p->tick;
    const uint32_t t_pos = p->n_settle, t_neg = t_pos + p->n_pulse, t_rel = t_neg + p->n_pulse;
    const uint32_t t_end = t_rel + p->n_release;
    memset(out, 0, sizeof(*out));
    out->result = p->result;
    out->asym = p->asym;
    if (p->result != POL_RUNNING) {
        return;
    }
    out->active = true;
    if (t == t_pos && !(in->conf >= p->cfg.conf_min)) {
        if (p->n_extra >= POL_SETTLE_EXTEND * p->n_settle) {
            p->result = POL_NO_LOCK;
            out->result = p->result;
            out->active = false;
            return;
        }
        p->n_extra++; /* not yet confident: settle on (the tick stays at the pulses' start) */
    }
    if (t < t_pos || (t == t_pos && !(in->conf >= p->cfg.conf_min))) {
        /* settling: a d-axis square wave (1 kHz at 20 kHz, a third of the pulse) so that the
         * MPCC's vectors carry the saliency while the PLL locks; no torque on the d axis */
        const uint32_t ts_ = t + p->n_extra;
        out->i_d_ref_a = ((ts_ / 10u) & 1u) != 0u ? -POL_SETTLE_EXCITE * p->cfg.i_pulse_a
                                                  : POL_SETTLE_EXCITE * p->cfg.i_pulse_a;
        if (t == t_pos) {
            return;
        }
    }
    if (t >= t_pos && t < t_rel) {
        const int side = t < t_neg ? 0 : 1;
        const uint32_t t0 = side == 0 ? t_pos : t_neg;
        out->i_d_ref_a = side == 0 ? p->cfg.i_pulse_a : -p->cfg.i_pulse_a;
        /* measure once the current has risen (the last two thirds of the pulse) */
        if (t - t0 >= p->n_pulse / 3u && in->excited) {
            p->sum_num[side] += in->di_d_a * in->u_d_v;
            p->sum_den[side] += p->cfg.ts_s * in->u_d_v * in->u_d_v;
        }
    }
    if (t + 1u == t_rel) {
        float g_pos = p->sum_den[0] > 0.0f ? p->sum_num[0] / p->sum_den[0] : 0.0f;
        float g_neg = p->sum_den[1] > 0.0f ? p->sum_num[1] / p->sum_den[1] : 0.0f;
        uint16_t r = pol_decide(&p->cfg, g_pos, g_neg, &p->asym);
        out->asym = p->asym;
        if (r == POL_UNRESOLVED) {
            p->result = r;
            out->result = r;
            out->active = false;
            return;
        }
        out->flip_now = r == POL_FLIPPED;
        p->pending = r;
    }
    p->tick++;
    if (p->tick >= t_end) {
        p->result = p->pending;
        out->result = p->result;
        out->active = false;
    }
}
