/* Hybrid angle source: PLL at low speed, MRAS above, bumpless blend (hybrid.h). */
#include "hybrid.h"

#include <math.h>
#include <string.h>

#include "transforms.h"

static uint32_t ticks_of(float t_s, float ts_s)
{
    float n = t_s / ts_s;
    if (!(n >= 1.0f)) {
        return 1u;
    }
    if (n > 1.0e8f) {
        return 100000000u;
    }
    return (uint32_t)(n + 0.5f);
}

void hyb_init(hyb_t *h, const hyb_cfg_t *cfg)
{
    memset(h, 0, sizeof(*h));
    h->cfg = *cfg;
    if (!(h->cfg.mras_on_rpm > h->cfg.pll_on_rpm)) {
        h->cfg.mras_on_rpm = h->cfg.pll_on_rpm * 1.5f + 1.0f;
    }
    h->dw = cfg->blend_s > cfg->ts_s ? cfg->ts_s / cfg->blend_s : 1.0f;
    h->rpm_per_rad_s = cfg->pole_pairs > 0u ? 9.5492966f / (float)cfg->pole_pairs : 9.5492966f;
    h->n_dis_max = ticks_of(cfg->disagree_s, cfg->ts_s);
    h->n_conf_max = ticks_of(cfg->lost_s, cfg->ts_s);
}

void hyb_step(hyb_t *h, const hyb_in_t *in, hyb_out_t *out)
{
    const float raw = tf_wrap_pi(in->theta_mras_rad - in->theta_pll_rad);
    /* the MRAS's angle enters the output only while it reports lock, agrees with the PLL within
     * disagree_rad and has not jumped since the last period (an MRAS losing its track jumps by up
     * to pi, sometimes a period before it reports the loss) */
    const float lim = h->cfg.disagree_rad;
    const bool trusted =
        in->mras_locked && fabsf(raw) < lim && fabsf(tf_wrap_pi(raw - h->raw_prev_rad)) < lim;
    const float diff = trusted ? raw : h->diff_held_rad;
    const float omega = in->omega_pll_rad_s;
    const float rpm = fabsf(omega) * h->rpm_per_rad_s;
    const bool both = rpm > h->cfg.pll_on_rpm && in->mras_locked;
    memset(out, 0, sizeof(*out));
    h->diff_held_rad = diff;
    h->raw_prev_rad = raw;
    if (rpm > h->cfg.mras_on_rpm && trusted) {
        h->to_mras = true;
    } else if (rpm < h->cfg.pll_on_rpm || !trusted) {
        h->to_mras = false;
    }
    h->w += h->to_mras ? h->dw : -h->dw;
    h->w = h->w > 1.0f ? 1.0f : (h->w < 0.0f ? 0.0f : h->w);
    if (both && fabsf(raw) > h->cfg.disagree_rad) {
        h->n_dis++;
    } else {
        h->n_dis = 0u;
    }
    if (h->w < 1.0f && !(in->conf_pll >= h->cfg.conf_min)) {
        h->n_conf++;
    } else {
        h->n_conf = 0u;
    }
    if (h->lock == HYB_LOCK_OK) {
        if (h->n_dis >= h->n_dis_max) {
            h->lock = HYB_LOCK_DISAGREE;
        } else if (h->n_conf >= h->n_conf_max) {
            h->lock = HYB_LOCK_LOW_CONF;
        }
    }
    out->diff_rad = raw;
    out->w_mras = h->w;
    out->theta_e_rad = tf_wrap_2pi(in->theta_pll_rad + h->w * diff);
    out->omega_e_rad_s = in->omega_pll_rad_s;
    out->lock = h->lock;
}
